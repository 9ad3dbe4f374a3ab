#include "pipeline/stages.hpp"

#include <cpl_conv.h>
#include <ogr_core.h>

#include <algorithm>
#include <memory>
#include <new>
#include <string>
#include <vector>

#include "common/config_option.hpp"
#include "common/host_info.hpp"
#include "common/openmp_threads.hpp"
#include "pipeline/staged_output.hpp"
#include "pipeline/tile_product.hpp"
#include "sites/fid_list.hpp"
#include "write/output_size.hpp"
#include "write/raster_writer.hpp"
#include "write/sqlite_write_behind.hpp"
#include "write/vector_writer.hpp"

namespace qtmv::pipeline {

bool RunProgress::report(double begin, double end, double fraction, const char* stage) {
  if (cancelled_) return false;
  if (!user_) return true;
  fraction = std::min(1.0, std::max(0.0, fraction));
  if (!user_(begin + (end - begin) * fraction, stage)) cancelled_ = true;
  return !cancelled_;
}

namespace {

/// Runs a stage's work: Interrupted passes, a stop asked for during a failure is a stop, any
/// other failure becomes a VoronoiError with `prefix` before its message.
template <class Work>
auto as_stage(RunProgress& progress, const std::string& prefix, Work&& work) -> decltype(work()) {
  try {
    return work();
  } catch (const Interrupted&) {
    throw;
  } catch (const VoronoiError&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw VoronoiError(prefix + "out of memory");
  } catch (const std::exception& e) {
    if (progress.cancelled()) throw Interrupted();
    throw VoronoiError(prefix + e.what());
  }
}

/// What becomes of the rows of sites without a cell in the output (vector_writer.hpp's EmptyRows).
std::string row_kept(const RunPlan& plan) {
  if (plan.format.raster || plan.tile_count > 0) return "";
  switch (write::empty_rows_of(plan.format.driver)) {
    case write::EmptyRows::empty: return "; they keep their row, with an empty geometry";
    case write::EmptyRows::null: return "; they keep their row, with a null geometry";
    case write::EmptyRows::left_out: return "; " + plan.format.driver + " cannot hold their rows (no geometry): they are left out";
  }
  return "";
}

/// Marks the sites that got no cell (SiteRecord::has_own_cell) from the cells per site, with one
/// warning naming them (they keep their row); returns their count.
std::uint64_t mark_sites_without_cell(const std::vector<std::uint64_t>& count, const RunPlan& plan,
                                      const MessageSink& messages, sites::SiteSet& sites) {
  sites::FidList missing;
  for (std::size_t s = 0; s < count.size(); ++s) {
    sites.table.sites[s].has_own_cell = count[s] > 0;
    if (count[s] == 0) missing.add(sites.table.sites[s].fid);
  }
  if (missing.count() > 0) {
    tell(messages, Severity::warning,
         std::to_string(missing.count()) + " site(s) got no cell of their own at level " + std::to_string(plan.level) +
             " (FIDs " + missing.text() + ")" + row_kept(plan));
  }
  return missing.count();
}

/// A raster's FID band names each site by its FID: refuses sites that share one (a -sql UNION of
/// two layers) or have none, which the band could not tell apart.
void check_raster_fids(const sites::SiteTable& table) {
  std::vector<std::int64_t> fids;
  fids.reserve(table.sites.size());
  for (const sites::SiteRecord& site : table.sites) fids.push_back(site.fid);
  std::sort(fids.begin(), fids.end());
  const std::string where = table.source_count() > 0 ? "'" + table.dataset() + "', layer '" + table.layer() + "': " : "";
  if (!fids.empty() && fids.front() == OGRNullFID) {
    throw VoronoiError(where + "sites without a FID: a raster's FID band cannot name them; write vector output, " +
                       "whose rows keep every site");
  }
  sites::FidList shared;  // each shared FID once
  for (std::size_t k = 1; k < fids.size(); ++k) {
    if (fids[k] == fids[k - 1] && (k == 1 || fids[k - 1] != fids[k - 2])) shared.add(fids[k]);
  }
  if (shared.count() == 0) return;
  const std::string all = shared.count() > sites::FidList::kListed ? " (" + std::to_string(shared.count()) + " in all)" : "";
  throw VoronoiError(where + "several sites share FID " + shared.text() + all + ": a raster's FID band could not tell " +
                     "them apart; write vector output (its rows keep every site), or give the sites unique FIDs");
}

/// Each site's layer and FID, in site order.
std::vector<SiteKey> site_keys(const sites::SiteTable& table) {
  std::vector<SiteKey> keys(table.sites.size());
  for (std::size_t s = 0; s < keys.size(); ++s) keys[s] = {table.sites[s].fid, table.sites[s].layer};
  return keys;
}

}  // namespace

sites::SiteSet read_stage(const std::string& source, const VoronoiOptions& options, const RunPlan& plan,
                          RunProgress& progress, const std::function<bool()>& between) {
  sites::ReadOptions read_options;
  static_cast<sites::SourceOptions&>(read_options) = options.read;
  read_options.level = plan.level;
  read_options.distance = options.rule;
  read_options.threads = options.threads;
  read_options.progress = [&](double f, const char* stage) {
    return (!between || between()) && progress.report(0.0, plan.read_end, f, stage);
  };
  // The reader's count of sites without a cell comes before labelling; the label stage reports
  // the final one instead.
  read_options.warn_sites_without_cell = false;
  read_options.messages = options.messages;
  // A tile job reads only the sites that can own a cell of its tile (sites/tile_selection.hpp).
  if (plan.tile_count > 0) read_options.tile_range = plan.label.range;
  if (!progress.report(0.0, plan.read_end, 0.0, "read")) throw Interrupted();
  return as_stage(progress, "", [&] { return sites::read_sites(source, read_options); });
}

LabelledLevel label_stage(sites::SiteSet& sites, const VoronoiOptions& options, const RunPlan& plan,
                          RunProgress& progress, std::uint64_t* without_cell) {
  // Vector output's products grow with the outlines, and so with the sites: checked now that
  // their number is known.
  check_run_memory(plan, options.memory_limit_bytes, sites.table.sites.size());
  label::LabelOptions label_options = plan.label;
  // The labeller reports between tiles, on this thread; false stops it with Interrupted.
  label_options.progress = [&](double f, const char* stage) {
    return progress.report(plan.read_end, plan.label_end, f, stage);
  };
  label_options.messages = options.messages;
  LabelledLevel out;
  label::LabelStats stats;
  if (plan.format.raster) check_raster_fids(sites.table);
  as_stage(progress, "labelling failed: ", [&] {
    if (plan.format.raster) {
      // A raster's labels come strip by strip from the session as it is written (which sites
      // got a cell is known then, from the pixels).
      // Its bands' labels only (run_plan): without the distance band, a tree without distances.
      const label::LabelOptions& session_options = label_options;
      out.session = std::make_unique<label::LabelSession>(sites.geometry.input(), session_options);
      stats = out.session->stats();
    } else {
      stats = label::label_outlines(sites.geometry.input(), label_options, &out.outlines);
    }
  });
  out.device = stats.device;
  out.prepare_seconds = stats.prepare_seconds;
  // A raster's sites are counted from its pixels; a tile's products hold only its own cells.
  if (plan.format.raster || plan.tile_count > 0) return out;
  *without_cell = mark_sites_without_cell(out.outlines.cells_per_site, plan, options.messages, sites);
  return out;
}

LabelledLevel merge_stage(const std::string& source, sites::SiteSet& sites, const VoronoiOptions& options,
                          const RunPlan& plan, RunProgress& progress, std::uint64_t* without_cell) {
  check_run_memory(plan, options.memory_limit_bytes, sites.table.sites.size());
  LabelledLevel out;
  MergeExpectation expect;
  expect.level = plan.level;
  expect.rule = options.rule;
  expect.site_count = static_cast<std::int32_t>(sites.table.sites.size());
  expect.site_fingerprints = site_fingerprints(sites.geometry.input());
  expect.site_keys = site_keys(sites.table);
  expect.source_features = sites.summary.features;
  expect.reading = reading_fingerprint(options.read);
  expect.source = "'" + source + "'";
  out.outlines = as_stage(progress, "", [&] {
    return merge_tile_products(plan.merge_files, expect,
                               [&](double f) { return progress.report(plan.read_end, plan.label_end, f, "merge"); });
  });
  out.device = "merged " + std::to_string(plan.merge_files.size()) + " tile products";
  *without_cell = mark_sites_without_cell(out.outlines.cells_per_site, plan, options.messages, sites);
  return out;
}

void write_tile_stage(const std::string& path, const std::string& destination, const LabelledLevel& labels,
                      const sites::SiteSet& sites, const VoronoiOptions& options, const RunPlan& plan) {
  TileProduct product;
  product.index = plan.tile_index;
  product.count = plan.tile_count;
  product.rule = options.rule;
  product.sites_fingerprint = sites_fingerprint(site_fingerprints(sites.geometry.input()));
  // A tile job that read only the sites near its tile names them in the whole source.
  if (sites.subset) {
    product.sites = site_keys(sites.table);
    product.source_features = sites.source_features;
    product.reading = reading_fingerprint(options.read);
  }
  product.outlines = labels.outlines;
  try {
    write_tile_product(path, product);
  } catch (const VoronoiError& e) {
    std::string message = e.what();
    replace_all(message, path, destination);  // name the destination, not the temporary file
    throw VoronoiError(message);
  }
}

namespace {

/// The labelling session as the raster writer's label source, timing its work.
class SessionSource : public write::CellLabelSource {
 public:
  explicit SessionSource(const label::LabelSession& session) : session_(session) {}
  int level() const override { return session_.level(); }
  bool has_distance() const override { return session_.has_distance(); }
  void label_range(grid::Code first, std::uint64_t count, std::int32_t* site, float* distance_m,
                   std::uint8_t* boundary) const override {
    const double t0 = now_seconds();
    session_.label_range(first, count, site, distance_m, boundary);
    seconds += now_seconds() - t0;
  }
  void label_codes(const grid::Code* codes, std::size_t count, std::int32_t* site, float* distance_m,
                   std::uint8_t* boundary) const override {
    const double t0 = now_seconds();
    session_.label_codes(codes, count, site, distance_m, boundary);
    seconds += now_seconds() - t0;
  }
  void label_parallels(const double* lat, int rows, const double* lon, std::size_t count, std::int32_t* site,
                       float* distance_m, std::uint8_t* boundary) const override {
    const double t0 = now_seconds();
    session_.label_parallels(lat, rows, lon, count, site, distance_m, boundary);
    seconds += now_seconds() - t0;
  }
  mutable double seconds = 0;  ///< spent labelling

 private:
  const label::LabelSession& session_;
};

}  // namespace

double write_stage(const std::string& path, const std::string& destination, const LabelledLevel& labels,
                   const sites::SiteSet& sites, const RunPlan& plan, RunProgress& progress, const MessageSink& messages,
                   std::uint64_t* without_cell) {
  const write::ProgressFunc write_progress = [&](double f, const char* stage) {
    return progress.report(plan.label_end, 1.0, f, stage);
  };
  double label_seconds = 0;
  try {
    const RenameInMessages name_the_destination(path, destination);
    if (!progress.report(plan.label_end, 1.0, 0.0, "write")) throw Interrupted();
    if (plan.format.raster) {
      write::RasterOptions raster_options = plan.raster;
      raster_options.progress = write_progress;
      if (!labels.session) throw VoronoiError(destination + ": no labelling session for the raster");
      const SessionSource source(*labels.session);
      write::RasterWritten written;
      try {
        written = write::write_raster(path, source, sites.table, raster_options);
      } catch (...) {
        label_seconds = source.seconds;
        throw;
      }
      label_seconds = source.seconds;
      // Sites that no pixel shows; say which (the QTM-coded raster has a pixel per cell).
      sites::FidList missing;
      for (std::size_t s = 0; s < written.site_seen.size(); ++s) {
        if (!written.site_seen[s]) missing.add(sites.table.sites[s].fid);
      }
      // A part's rows show some of the sites: the whole raster's are the parts' together.
      if (plan.part) missing = sites::FidList();
      *without_cell = missing.count();
      if (missing.count() > 0) {
        const std::string fids = " (FIDs " + missing.text() + ")";
        tell(messages, Severity::warning,
             std::to_string(missing.count()) +
                 (plan.raster.layout == write::RasterOptions::Layout::qtm
                      ? " site(s) got no cell of their own at level " + std::to_string(plan.level) + fids
                      : " site(s) hold no pixel of the raster" + fids + ": their cells of level " +
                            std::to_string(plan.level) + ", if any, hold no pixel's centre (a finer -tr or -ts may "
                            "show them)"));
      }
    } else {
      write::VectorOptions vector_options = plan.vector;
      vector_options.progress = write_progress;
      vector_options.messages = messages;
      // The cells layer: every cell's labels again, tile by tile, as the layer writes them.
      const write::CellTileSource cell_tiles = [&](const std::function<void(const write::CellTile&)>& sink) {
        label::LabelOptions label_options = plan.label;
        label_options.want_distance = true;
        label_options.want_boundary = true;
        label::label_cells(sites.geometry.input(), label_options, [&](const label::LabelTile& tile) {
          sink({tile.first, tile.count, tile.site, tile.distance_m, tile.boundary});
        });
      };
      // A temporary file, renamed into place only after a clean close, needs no durability
      // while it is written: no fsync, no rollback journal (nothing is rolled back; a failed
      // write is removed). Only where the user has not set these, and never for a direct write.
      // A large file gets SQLite's largest pages (write/output_size.hpp says why), and a SQLite
      // file is written behind its connection (write/sqlite_write_behind.hpp).
      std::unique_ptr<CPLConfigOptionSetter> no_sync, no_journal, page_size;
      std::unique_ptr<write::SqliteWriteBehind> write_behind;
      if (path != destination) {
        // Its own thread: not where the run has one (-threads 1).
        const char* behind = config_option("QTMV_WRITE_BEHIND");
        if ((behind == nullptr || config_flag("QTMV_WRITE_BEHIND")) && thread_count(0) > 1) {
          write_behind = std::make_unique<write::SqliteWriteBehind>(path);
        }
        no_sync = std::make_unique<CPLConfigOptionSetter>("OGR_SQLITE_SYNCHRONOUS", "OFF", true);
        no_journal = std::make_unique<CPLConfigOptionSetter>("OGR_SQLITE_JOURNAL", "OFF", true);
        const std::uint32_t page = write::sqlite_page_size(
            write::expected_vector_bytes(plan.level, vector_options, labels.outlines.cells.size()));
        if (page != 0) {
          page_size = std::make_unique<CPLConfigOptionSetter>("OGR_SQLITE_PRAGMA", ("page_size=" + std::to_string(page)).c_str(), true);
        }
      }
      write::write_vector(path, labels.outlines, cell_tiles, sites.table, vector_options);
    }
    // A stop asked for during the close is honoured too: nothing is renamed yet.
    if (!progress.report(plan.label_end, 1.0, 1.0, "write")) throw Interrupted();
    return label_seconds;
  } catch (const Interrupted&) {
    throw;
  } catch (const std::exception& e) {
    if (progress.cancelled()) throw Interrupted();
    std::string message = e.what();
    replace_all(message, path, destination);  // name the destination, not the temporary file
    throw VoronoiError(message);
  }
}

}  // namespace qtmv::pipeline
