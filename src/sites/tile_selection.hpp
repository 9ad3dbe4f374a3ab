// A tile job's sites (-tile K/N): only the features that can own a cell of its codes, so that N
// tile jobs read about the sites once in all, with the whole run's labels.
//
// The tile's cells and their neighbours lie in caps around coarse cells (a cell of a coarser
// level whose rows meet the tile: centre c, radius r). Each cap is read with a reach T: OGR
// spatial filters (rectangles in the layer's CRS, each read in turn) give every feature within
// r + T of c. Then it is verified: some feature read has a point closer to c than T - r; so every
// cell of the cap has a site read closer than T, while every feature not read is farther than T
// from it: none can own the cell, nor tie. A cap that fails is read again with twice the reach.
// The features are handed over in FID order, the order of a read of the whole layer (what the
// merge checks), so that ties go to the same (lower) site as in the whole run.
//
// Exact only where a feature's envelope in its layer's CRS holds what the reader makes of it:
// points in any CRS; lines and polygons in a geographic CRS with -edges lonlat, where no edge
// is joined across +-180 (-wrap none, or a layer narrower than 180 degrees). Elsewhere (-sql, a
// layer without a spatial index, features without FIDs, a transformation that fails) every
// feature is read, as in a whole run, and the read trace says why.
#pragma once

#include <string>
#include <vector>

#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include "gdal/error_capture.hpp"
#include "sites/ogr_source.hpp"
#include "sites/site_options.hpp"

namespace qtmv::sites {

/// The features a tile job reads.
struct TileSelection {
  bool used = false;  ///< false: every feature is read (`why` says why)
  std::string why;    ///< why not, or what was read (for the read trace)
  std::uint64_t source_features = 0;  ///< of the source's layers (after -where), as GDAL counts them
  std::vector<std::vector<OGRFeatureUniquePtr>> features;  ///< per layer of the source, by FID
};

/// The features of `source`'s layers that can own a cell of options.tile_range (set) at
/// options.level, with options.where applied. Throws Interrupted when options.progress says stop;
/// never fails otherwise: a source it cannot select from is read whole (used = false).
TileSelection select_tile_features(const OgrSource& source, const ReadOptions& options, gdal::ErrorCapture& errors,
                                   const OGRSpatialReference& wgs84);

}  // namespace qtmv::sites
