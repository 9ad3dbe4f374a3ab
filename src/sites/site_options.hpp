// Options, messages and errors of the readers (GDAL-utility style: an options struct, a progress
// callback and a message sink; errors are exceptions naming the file, layer and FID, never exit()).
#pragma once

#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/run_context.hpp"
#include "label/label_options.hpp"

namespace qtmv::sites {

/// Shape of a segment between two consecutive vertices of a line or ring.
enum class EdgeShape {
  lonlat,    ///< straight in lon/lat (how GIS software draws EPSG:4326 data)
  geodesic,  ///< shortest path on the WGS84 ellipsoid (GeographicLib)
};

/// How longitude jumps across +-180 are read.
enum class WrapMode {
  automatic,  ///< vertices more than 180 degrees apart are joined the short way across +-180
  none,       ///< coordinates are flat lon/lat
};

/// The distance rule (label_options.hpp): one enum from reading to labelling.
using DistanceRule = label::Rule;

// The run's plumbing (common/run_context.hpp): a progress callback returning false stops the
// reading with Interrupted.
using qtmv::Interrupted;
using qtmv::MessageSink;
using qtmv::ProgressFunc;
using qtmv::Severity;

/// What to read and how to read it: the reader options a caller of the pipeline gives.
struct SourceOptions {
  /// -l: the layers to read; several make composite sites (each layer's after the one before,
  /// FIDs their layer's); empty: the first layer.
  std::vector<std::string> layers;
  std::string where;             ///< -where: attribute filter (OGR SQL expression)
  std::string sql;               ///< -sql: statement whose result set is read instead of a layer
  std::string dialect;           ///< -dialect: SQL dialect of -sql ("OGRSQL", "SQLITE", ...)
  std::string source_srs;        ///< -s_srs: overrides the layer's CRS (any OGRSpatialReference input)
  std::vector<std::string> open_options;  ///< -oo NAME=VALUE: the driver's open options
  EdgeShape edges = EdgeShape::lonlat;       ///< -edges lonlat|geodesic
  WrapMode wrap = WrapMode::automatic;       ///< -wrap auto|none
  bool strict = false;           ///< -strict: a skipped feature or an invalid polygon is an error
  bool make_valid = false;       ///< -makevalid: invalid polygons repaired by OGR's MakeValid
};

/// The reader's options: the source's, and those of the run it is part of.
struct ReadOptions : SourceOptions {
  int level = label::kDefaultLevel;             ///< QTM level (0..24)
  DistanceRule distance = DistanceRule::exact;  ///< -distance exact|cell
  /// Warn about sites left with no cell of their own by the claims. A caller that labels the
  /// grid afterwards turns this off and reports the final count itself.
  bool warn_sites_without_cell = true;
  /// Threads of the read, the calling thread among them (it reads the features with GDAL and
  /// reports them in feature order; the others check, transform, trace and fill them beside
  /// it); 0: all (OpenMP's default). The result is the same for any.
  int threads = 0;
  /// A tile job's codes (-tile K/N, whole rows of `level`): only the sites that can own one of
  /// them are read where the source allows (tile_selection.hpp); empty (the default): every site.
  grid::CodeRange tile_range;
  ProgressFunc progress;         ///< may be empty
  MessageSink messages;          ///< may be empty (messages are then dropped)
};

/// A reading error: unreadable input, a bad option, -strict and a bad feature, no usable site.
/// The command line reports what() and exits with status 1.
class ReadError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// `text` with GDAL's messages (ErrorCapture::take), when there are some: "text (GDAL: ...)".
inline std::string with_gdal_message(std::string text, const std::string& gdal) {
  if (!gdal.empty()) text += " (GDAL: " + gdal + ")";
  return text;
}

EdgeShape parse_edge_shape(const std::string& text);    ///< "lonlat" | "geodesic"; throws ReadError
WrapMode parse_wrap_mode(const std::string& text);      ///< "auto" | "none"; throws ReadError
DistanceRule parse_distance_rule(const std::string& text);  ///< "exact" | "cell"; throws ReadError

}  // namespace qtmv::sites
