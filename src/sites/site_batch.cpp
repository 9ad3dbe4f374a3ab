#include "sites/site_batch.hpp"

#include <algorithm>
#include <chrono>
#include <utility>

#include "common/openmp_threads.hpp"

namespace qtmv::sites {

namespace {

/// A feature with more vertices than this is shared out by its parts (whole polygons), so that
/// one large multipolygon (a continent's coasts) keeps several threads busy.
constexpr std::size_t kShareVertices = std::size_t{1} << 12;
/// Jobs built as one unit of work (a slice): worth a thread (a few hundred points), and no more
/// work than a share. A line or ring counts as kPathWork vertices more than it has (filling a
/// polygon costs more than its vertices say), so that slices of lines and polygons stay small
/// enough to be shared out.
constexpr std::size_t kSliceJobs = 256;
constexpr std::size_t kPathWork = 256;

/// A job's work, for the slices' size.
std::size_t work_of(const SiteJob& job) {
  std::size_t paths = 0;
  for (std::size_t p = 0; p < job.part_count; ++p) paths += job.parts[p].kind != FeatureParts::kPoint;
  return job.vertices + kPathWork * paths;
}

/// Traces and fills one site with `builder` (a polygon's rings together).
void build_site(SiteBuilder& builder, const SiteJob& job) {
  builder.begin_site();
  for (std::size_t p = 0; p < job.part_count;) {
    const FeatureParts::Part& part = job.parts[p];
    if (part.kind == FeatureParts::kPoint) {
      builder.add_point(job.points[part.begin]);
      ++p;
    } else if (part.kind == FeatureParts::kLine) {
      builder.add_line(job.points + part.begin, part.end - part.begin);
      ++p;
    } else {
      std::vector<LonLatPath> rings;
      const int polygon = part.polygon;
      for (; p < job.part_count && job.parts[p].kind == FeatureParts::kRing && job.parts[p].polygon == polygon; ++p) {
        rings.emplace_back(job.points + job.parts[p].begin, job.points + job.parts[p].end);
      }
      builder.add_polygon(rings);
    }
  }
  builder.end_site();
}

}  // namespace

SiteBuilders::SiteBuilders(const ReadOptions& options, int threads)
    : level_(options.level), edges_(options.edges), wrap_(options.wrap), builders_(static_cast<std::size_t>(threads)) {}

SiteBuilder& SiteBuilders::of_this_thread() {
  std::unique_ptr<SiteBuilder>& builder = builders_[static_cast<std::size_t>(thread_index())];
  if (!builder) builder = std::make_unique<SiteBuilder>(level_, edges_, wrap_);
  return *builder;
}

std::uint64_t SiteBuilders::vertex_steps() const {
  std::uint64_t steps = 0;
  for (const auto& builder : builders_) steps += builder ? builder->vertex_steps() : 0;
  return steps;
}

// The feature's parts as jobs: one, or shares of about kShareVertices vertices, split between
// polygons (a polygon's rings stay together). The split depends on the feature only.
void SiteBatch::add(GIntBig fid, std::int32_t site, const FeatureParts& parts, std::size_t part_begin,
                    std::size_t part_end) {
  const FeatureParts::Part* const all = parts.parts.data();
  SiteJob job{fid, site, true, parts.points.data(), all + part_begin, 0, 0, 0};
  for (std::size_t p = part_begin; p < part_end; ++p) {
    const bool polygon_starts = all[p].kind != FeatureParts::kRing || p == part_begin ||
                                all[p - 1].kind != FeatureParts::kRing || all[p - 1].polygon != all[p].polygon;
    if (polygon_starts && job.vertices >= kShareVertices) {
      jobs_.push_back(job);
      job = SiteJob{fid, site, false, parts.points.data(), all + p, 0, 0, 0};
    }
    ++job.part_count;
    job.vertices += all[p].end - all[p].begin;
  }
  jobs_.push_back(job);
}

void SiteBatch::plan_slices() {
  slice_count_ = 0;
  for (std::size_t k = 0; k < jobs_.size();) {
    std::size_t last = k, work = 0;
    while (last < jobs_.size() && last - k < kSliceJobs) {
      const std::size_t job_work = work_of(jobs_[last]);
      if (last > k && work + job_work > kShareVertices) break;
      work += job_work;
      ++last;
    }
    if (slice_count_ == slices_.size()) slices_.emplace_back();
    slices_[slice_count_].first = k;
    slices_[slice_count_++].last = last;
    k = last;
  }
}

void SiteBatch::build_slice(std::size_t s, SiteBuilders& builders, ReadTimes& times) {
  BuiltSlice& slice = slices_[s];
  SiteGeometry& out = slice.geometry;
  out.level = builders.level();
  out.site_count = 0;
  out.pieces.clear();
  out.site_cells.clear();
  out.fixed_cells.clear();
  out.fixed_nodes.clear();
  SiteBuilder& builder = builders.of_this_thread();
  std::swap(builder.geometry(), out);  // the builder adds to the slice's arrays, its sites counted from 0
  double longest = 0;
  for (std::size_t k = slice.first; k < slice.last; ++k) {
    const auto start = times.time_jobs ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point{};
    build_site(builder, jobs_[k]);
    if (times.time_jobs) longest = std::max(longest, seconds_since(start));
    jobs_[k].short_way_edges = builder.short_way_edges();
  }
  std::swap(builder.geometry(), out);
  if (times.time_jobs) {
#pragma omp critical(qtmv_read_trace)
    times.longest_job_s = std::max(times.longest_job_s, longest);
  }
}

void SiteBatch::name_wrapped(FidList& wrapped, GIntBig& last_named) const {
  for (const SiteJob& job : jobs_) {
    const bool named = !job.starts_site && last_named == job.fid;
    if (job.short_way_edges > 0 && !named) {
      wrapped.add(job.fid);
      last_named = job.fid;
    }
  }
}

void SiteBatch::clear() {
  jobs_.clear();
  slice_count_ = 0;
}

}  // namespace qtmv::sites
