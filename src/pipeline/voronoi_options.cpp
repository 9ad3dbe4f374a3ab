#include "pipeline/voronoi_options.hpp"

#include <cstdio>
#include <sstream>
#include <string>

namespace qtmv {

namespace {

std::string seconds(double s) {
  char text[64];
  std::snprintf(text, sizeof text, "%.2f s", s);
  return text;
}

}  // namespace

std::string VoronoiSummary::line() const {
  std::ostringstream s;
  s << sites << " site" << (sites == 1 ? "" : "s") << " read, " << skipped << " skipped";
  if (invalid_polygons > 0) {
    s << ", " << invalid_polygons << " with an invalid polygon";
    if (repaired_polygons > 0) s << " (" << repaired_polygons << " repaired)";
  }
  s << "; level " << level << ", " << cells << " cells";
  if (tile_count > 0) s << ", tile " << tile_index << "/" << tile_count;
  s << "; " << device << "; read " << seconds(read_seconds) << " (rasterise " << seconds(rasterise_seconds) << "), label " << seconds(label_seconds)
    << " (prepare " << seconds(prepare_seconds) << "), write " << seconds(write_seconds) << "; total "
    << seconds(total_seconds);
  return s.str();
}

}  // namespace qtmv
