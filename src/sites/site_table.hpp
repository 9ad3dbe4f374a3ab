// The site table: per site, where it came from (FID, attributes) and what it got (cell counts),
// for the writers and the summary.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <ogr_feature.h>

namespace qtmv::sites {

/// Deletes an OGRFeature with GDAL's allocator.
struct FeatureDeleter {
  void operator()(OGRFeature* feature) const { OGRFeature::DestroyFeature(feature); }
};
using FeaturePtr = std::unique_ptr<OGRFeature, FeatureDeleter>;

/// What kinds of geometry a site is made of (a bit set: a collection may mix them).
enum SiteKind : unsigned { kPointSite = 1, kLineSite = 2, kPolygonSite = 4 };

struct SiteRecord {
  std::int64_t fid = -1;        ///< the feature's FID (OGRNullFID when the source has none)
  FeaturePtr attributes;        ///< the feature's fields, without its geometry (holds a reference to the definition)
  unsigned kind = 0;            ///< SiteKind bits
  std::uint64_t site_cells = 0;   ///< distinct cells the site passes through
  std::uint64_t fixed_cells = 0;  ///< cells inside its polygons that it holds
  bool has_own_cell = false;    ///< false: every cell it has went to another site (it is still written)
};

/// The sites in id order (site id = index), and the field definitions they share.
class SiteTable {
 public:
  SiteTable() = default;
  SiteTable(SiteTable&&) noexcept;
  SiteTable& operator=(SiteTable&&) noexcept;
  SiteTable(const SiteTable&) = delete;
  SiteTable& operator=(const SiteTable&) = delete;
  ~SiteTable();

  /// Sets the field definitions (a reference is kept) and the source's description.
  void set_source(OGRFeatureDefn* definition, std::string dataset, std::string layer);
  /// The fields of every site, or null before set_source.
  const OGRFeatureDefn* definition() const { return definition_; }
  const std::string& dataset() const { return dataset_; }
  const std::string& layer() const { return layer_; }

  std::vector<SiteRecord> sites;

 private:
  OGRFeatureDefn* definition_ = nullptr;
  std::string dataset_, layer_;
};

}  // namespace qtmv::sites
