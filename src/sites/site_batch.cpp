#include "sites/site_batch.hpp"

#include <algorithm>
#include <chrono>
#include <utility>

#include "common/first_exception.hpp"
#include "common/openmp_threads.hpp"
#include "sites/append_sites.hpp"

namespace qtmv::sites {

namespace {

/// Jobs and coordinates per batch: enough work for every thread, memory bounded.
constexpr std::size_t kBatchSites = 4096;
constexpr std::size_t kBatchVertices = std::size_t{1} << 22;
/// A feature with more vertices than this is shared out by its parts (whole polygons), so that
/// one large multipolygon (a continent's coasts) keeps several threads busy.
constexpr std::size_t kShareVertices = std::size_t{1} << 12;

/// The feature's parts as jobs: one, or shares of about kShareVertices vertices, split between
/// polygons (a polygon's rings stay together). The split depends on the feature only.
void make_jobs(GIntBig fid, std::vector<grid::LonLat>&& lonlat, std::vector<FeatureParts::Part>&& parts,
               std::vector<SiteJob>& out) {
  auto shared = std::make_shared<const std::vector<grid::LonLat>>(std::move(lonlat));
  SiteJob job{fid, true, shared, {}};
  std::size_t vertices = 0;
  for (std::size_t p = 0; p < parts.size(); ++p) {
    const bool polygon_starts = parts[p].kind != FeatureParts::kRing || p == 0 ||
                                parts[p - 1].kind != FeatureParts::kRing || parts[p - 1].polygon != parts[p].polygon;
    if (polygon_starts && vertices >= kShareVertices) {
      out.push_back(std::move(job));
      job = SiteJob{fid, false, shared, {}};
      vertices = 0;
    }
    job.parts.push_back(parts[p]);
    vertices += parts[p].end - parts[p].begin;
  }
  out.push_back(std::move(job));
}

/// Traces and fills one site with `builder` (a polygon's rings together).
void build_site(SiteBuilder& builder, const SiteJob& job) {
  builder.begin_site();
  for (std::size_t p = 0; p < job.parts.size();) {
    const FeatureParts::Part& part = job.parts[p];
    if (part.kind == FeatureParts::kPoint) {
      builder.add_point((*job.lonlat)[part.begin]);
      ++p;
    } else if (part.kind == FeatureParts::kLine) {
      builder.add_line(job.lonlat->data() + part.begin, part.end - part.begin);
      ++p;
    } else {
      std::vector<LonLatPath> rings;
      const int polygon = part.polygon;
      for (; p < job.parts.size() && job.parts[p].kind == FeatureParts::kRing && job.parts[p].polygon == polygon; ++p) {
        rings.emplace_back(job.lonlat->begin() + job.parts[p].begin, job.lonlat->begin() + job.parts[p].end);
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

void SiteBatch::add(GIntBig fid, std::vector<grid::LonLat>&& lonlat, std::vector<FeatureParts::Part>&& parts) {
  vertices_ += lonlat.size();
  make_jobs(fid, std::move(lonlat), std::move(parts), jobs_);
}

bool SiteBatch::full() const { return jobs_.size() >= kBatchSites || vertices_ >= kBatchVertices; }

void SiteBatch::build() {
  if (jobs_.empty()) return;
  const int threads = builders_.threads();
  const auto start = std::chrono::steady_clock::now();
  const auto n = static_cast<std::int64_t>(jobs_.size());
  std::vector<SiteGeometry> built(jobs_.size());
  std::vector<std::size_t> short_way(jobs_.size(), 0);
  FirstException failure;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (std::int64_t k = 0; k < n; ++k) {
    failure.run([&] {
      SiteBuilder& builder = builders_.of_this_thread();
      const double job_start = times_.time_jobs ? seconds_since(start) : 0.0;
      build_site(builder, jobs_[static_cast<std::size_t>(k)]);
      if (times_.time_jobs) {
        const double job = seconds_since(start) - job_start;
#pragma omp critical(qtmv_read_trace)
        times_.longest_job_s = std::max(times_.longest_job_s, job);
      }
      short_way[k] = builder.short_way_edges();
      built[k] = builder.take_geometry();
    });
  }
  failure.rethrow();
  // A feature's shares come one after another: its first starts the site, the others add to it.
  // Appended batch by batch: holding every batch's built sites until the end of the read made
  // the runs of 135 000 points peak 500 MB higher (measured at level 13), for no gain in time.
  std::vector<std::int32_t> ids(jobs_.size());
  std::int32_t next_id = geometry_.site_count;
  for (std::size_t k = 0; k < jobs_.size(); ++k) ids[k] = jobs_[k].starts_site ? next_id++ : next_id - 1;
  const double append_start = seconds_since(start);
  append_sites(geometry_, built, ids, threads);
  times_.built_s += append_start;
  times_.appended_s += seconds_since(start) - append_start;
  for (std::size_t k = 0; k < jobs_.size(); ++k) {
    const bool named = !jobs_[k].starts_site && wrapped_fid_ == jobs_[k].fid;
    if (short_way[k] > 0 && !named) {
      wrapped_.add(jobs_[k].fid);
      wrapped_fid_ = jobs_[k].fid;
    }
  }
  jobs_.clear();
  vertices_ = 0;
  times_.rasterise += std::chrono::steady_clock::now() - start;
}

}  // namespace qtmv::sites
