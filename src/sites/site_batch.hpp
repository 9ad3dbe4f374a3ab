// Sites are traced and filled in batches (a chunk's features) on all threads: the jobs (a
// feature, or a share of a large one's parts) in slices of consecutive jobs, each slice built by
// one thread's builder into the slice's own arrays, which keep their memory from chunk to chunk;
// then appended in feature order (append_sites): the same geometry whatever the thread count.
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
  /// The calling thread's builder (of an OpenMP team of threads() threads at most).
  SiteBuilder& of_this_thread();
  /// The level the sites are built at.
  int level() const { return level_; }
  /// Cell pairs sharing only a vertex accepted while tracing, by every builder.
  std::uint64_t vertex_steps() const;

 private:
  int level_;
  EdgeShape edges_;
  WrapMode wrap_;
  std::vector<std::unique_ptr<SiteBuilder>> builders_;
};

/// A feature's site, or a share of its parts, to be traced and filled.
struct SiteJob {
  GIntBig fid = 0;
  std::int32_t site = 0;     ///< its site's id
  bool starts_site = true;   ///< the first share of its feature (the others add to its site)
  const grid::LonLat* points = nullptr;     ///< the coordinates its parts index (lon/lat degrees)
  const FeatureParts::Part* parts = nullptr;
  std::size_t part_count = 0;
  std::size_t vertices = 0;
  std::size_t short_way_edges = 0;  ///< found by the build: edges -wrap auto joined across +-180
};

/// Consecutive jobs built by one thread into their own arrays (site ids counted from 0 there,
/// one per job).
struct BuiltSlice {
  std::size_t first = 0, last = 0;  // jobs
  SiteGeometry geometry;
};

/// One batch's jobs, gathered in feature order, then built slice by slice on any thread.
class SiteBatch {
 public:
  /// Adds site `site` of feature `fid`: its parts [part_begin, part_end) of `parts` (coordinates
  /// in lon/lat degrees; `parts` must stay as it is until the batch is built), as jobs.
  void add(GIntBig fid, std::int32_t site, const FeatureParts& parts, std::size_t part_begin, std::size_t part_end);
  /// Cuts the jobs into slices (after the last add).
  void plan_slices();
  std::size_t slice_count() const { return slice_count_; }
  /// Builds slice `s` with the calling thread's builder: called on any thread, once per slice.
  void build_slice(std::size_t s, SiteBuilders& builders, ReadTimes& times);
  /// The built slices and their jobs, for append_sites.
  const std::vector<BuiltSlice>& slices() const { return slices_; }
  const std::vector<SiteJob>& jobs() const { return jobs_; }
  /// Adds the features whose edges -wrap auto joined across +-180 (after the build) to
  /// `wrapped`, each once (`last_named`: the last feature named, from batch to batch).
  void name_wrapped(FidList& wrapped, GIntBig& last_named) const;
  /// Forgets the jobs (the slices' memory kept for the next batch).
  void clear();

 private:
  std::vector<SiteJob> jobs_;
  std::vector<BuiltSlice> slices_;  // the first slice_count_ in use
  std::size_t slice_count_ = 0;
};

}  // namespace qtmv::sites
