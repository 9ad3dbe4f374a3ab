// The stages of a run after its plan (run_plan.hpp): read the sites, label the level, write the
// destination. Each takes the products of the one before as plain data: sites::SiteSet, then
// label::Outlines (vector output: memory that follows the outlines) or a label::LabelSession (a
// raster: the labeller prepared once, asked for each strip's labels as the raster is written).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "common/run_context.hpp"
#include "label/label_session.hpp"
#include "label/labeller.hpp"
#include "label/outline_cells.hpp"
#include "pipeline/run_plan.hpp"
#include "sites/ogr_site_reader.hpp"

namespace qtmv::pipeline {

/// Maps each stage's progress onto its slice of the whole run and remembers a request to stop.
class RunProgress {
 public:
  explicit RunProgress(const ProgressFunc& user) : user_(user) {}
  /// Reports `fraction` of the slice [begin, end] of the run; false once the user asked to stop.
  bool report(double begin, double end, double fraction, const char* stage);
  bool cancelled() const { return cancelled_; }

 private:
  const ProgressFunc& user_;
  bool cancelled_ = false;
};

/// What the label stage hands the write stage: outlines for vector output; for a raster, the
/// labelling session the writer streams from.
struct LabelledLevel {
  label::Outlines outlines;
  std::unique_ptr<label::LabelSession> session;
  std::string device;           ///< where the labelling ran
  double prepare_seconds = 0;   ///< the labeller's candidates and tree
};

/// Reads and rasterises the sites (progress in [0, plan.read_end]). Throws VoronoiError naming
/// the source, or Interrupted.
/// `between`, if set, is asked at each of the reader's progress reports whether to go on (false
/// stops the read with Interrupted): run_voronoi checks the devices there once they are counted.
sites::SiteSet read_stage(const std::string& source, const VoronoiOptions& options, const RunPlan& plan,
                          RunProgress& progress, const std::function<bool()>& between = {});

/// Labels the level (progress in [plan.read_end, plan.label_end]) and marks the sites that got
/// no cell (SiteRecord::has_own_cell), with one warning naming them; their count goes to
/// *without_cell. For a raster it only prepares the labelling session (the write stage then
/// counts and names the sites without a pixel). Throws VoronoiError, or Interrupted.
LabelledLevel label_stage(sites::SiteSet& sites, const VoronoiOptions& options, const RunPlan& plan,
                          RunProgress& progress, std::uint64_t* without_cell);

/// A merge's label stage (plan.merge_files): the tile products joined into the level's outlines
/// (pipeline/tile_product.hpp), checked against the sites read now; then as label_stage.
/// Throws VoronoiError naming the tile product at fault, or Interrupted.
LabelledLevel merge_stage(const std::string& source, sites::SiteSet& sites, const VoronoiOptions& options,
                          const RunPlan& plan, RunProgress& progress, std::uint64_t* without_cell);

/// A tile job's write stage: its tile's outlines as a tile product at `path`, named as the
/// destination in every message. Throws VoronoiError.
void write_tile_stage(const std::string& path, const std::string& destination, const LabelledLevel& labels,
                      const sites::SiteSet& sites, const VoronoiOptions& options, const RunPlan& plan);

/// Writes the destination from the labels (progress in [plan.label_end, 1]): into the staged
/// output's temporary path, named as the destination in every message. For the cells layer the
/// level is labelled again, tile by tile; a raster asks the session for each strip's labels.
/// A raster's sites that no pixel holds are named in one warning to `messages`, and counted in
/// *without_cell (the QTM-coded raster: sites without a cell). Returns the seconds spent
/// labelling strips (part of the stage's time). Throws VoronoiError, or Interrupted.
double write_stage(const std::string& path, const std::string& destination, const LabelledLevel& labels,
                   const sites::SiteSet& sites, const RunPlan& plan, RunProgress& progress, const MessageSink& messages,
                   std::uint64_t* without_cell);

}  // namespace qtmv::pipeline
