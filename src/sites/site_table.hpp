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
  std::uint32_t layer = 0;      ///< the source layer it was read from (SiteTable::definition(layer), ...)
};

/// The sites in id order (site id = index), and the source layers they were read from: one, or
/// several for composite sites (several -l), each with its own field definitions.
class SiteTable {
 public:
  SiteTable() = default;
  SiteTable(SiteTable&&) noexcept;
  SiteTable& operator=(SiteTable&&) noexcept;
  SiteTable(const SiteTable&) = delete;
  SiteTable& operator=(const SiteTable&) = delete;
  ~SiteTable();

  /// Sets the only source layer: its field definitions (a reference is kept) and its names.
  void set_source(OGRFeatureDefn* definition, std::string dataset, std::string layer);
  /// Adds a source layer; returns the index its sites hold in SiteRecord::layer.
  std::uint32_t add_source(OGRFeatureDefn* definition, std::string dataset, std::string layer);

  /// The source layers (0 before set_source or add_source).
  std::size_t source_count() const { return sources_.size(); }
  /// The fields of source layer k's sites (of every site when there is one layer), or null
  /// when there is no such layer.
  const OGRFeatureDefn* definition(std::size_t k = 0) const {
    return k < sources_.size() ? sources_[k].definition : nullptr;
  }
  const std::string& dataset(std::size_t k = 0) const { return sources_.at(k).dataset; }
  const std::string& layer(std::size_t k = 0) const { return sources_.at(k).layer; }

  std::vector<SiteRecord> sites;

 private:
  struct Source {
    OGRFeatureDefn* definition = nullptr;
    std::string dataset, layer;
  };
  void release_sources();
  std::vector<Source> sources_;
};

}  // namespace qtmv::sites
