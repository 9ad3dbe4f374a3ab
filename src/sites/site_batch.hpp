// Sites are traced and filled in batches on all threads, each job (a feature, or a share of a
// large one's parts) by one thread's builder, and appended in feature order: the same geometry
// whatever the thread count.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include <cpl_port.h>

#include "grid/qtm_geometry.hpp"
#include "sites/feature_parts.hpp"
#include "sites/fid_list.hpp"
#include "sites/read_times.hpp"
#include "sites/site_builder.hpp"
#include "sites/site_options.hpp"
#include "sites/site_types.hpp"

namespace qtmv::sites {

/// One site builder per thread, made on first use and kept from batch to batch and layer to
/// layer.
class SiteBuilders {
 public:
  SiteBuilders(const ReadOptions& options, int threads);
  /// The threads the batches run on.
  int threads() const { return static_cast<int>(builders_.size()); }
  /// The calling thread's builder (of an OpenMP team of threads() threads).
  SiteBuilder& of_this_thread();
  /// Cell pairs sharing only a vertex accepted while tracing, by every builder.
  std::uint64_t vertex_steps() const;

 private:
  int level_;
  EdgeShape edges_;
  WrapMode wrap_;
  std::vector<std::unique_ptr<SiteBuilder>> builders_;
};

/// A feature's site, or a share of its parts, to be traced and filled: its coordinates (lon/lat,
/// shared by the shares) and parts.
struct SiteJob {
  GIntBig fid = 0;
  bool starts_site = true;  ///< the first share of its feature (the others add to its site)
  std::shared_ptr<const std::vector<grid::LonLat>> lonlat;
  std::vector<FeatureParts::Part> parts;
};

/// One layer's batches: jobs gathered in feature order, built when the batch is full and at the
/// end of the layer, appended to the read's geometry.
class SiteBatch {
 public:
  SiteBatch(SiteBuilders& builders, SiteGeometry& geometry, ReadTimes& times)
      : builders_(builders), geometry_(geometry), times_(times) {}

  /// Adds feature `fid`'s site, its lon/lat coordinates (degrees) and parts, as jobs.
  void add(GIntBig fid, std::vector<grid::LonLat>&& lonlat, std::vector<FeatureParts::Part>&& parts);
  /// Whether the batch holds enough work for every thread (memory bounded): build it.
  bool full() const;
  /// Traces and fills the batch's jobs on all threads, appends their sites in feature order and
  /// empties the batch.
  void build();
  /// The features -wrap auto changed (edges joined the short way across +-180), so far.
  const FidList& wrapped() const { return wrapped_; }

 private:
  SiteBuilders& builders_;
  SiteGeometry& geometry_;
  ReadTimes& times_;
  std::vector<SiteJob> jobs_;
  std::size_t vertices_ = 0;
  FidList wrapped_;
  GIntBig wrapped_fid_ = -1;  // the last feature named in `wrapped_`
};

}  // namespace qtmv::sites
