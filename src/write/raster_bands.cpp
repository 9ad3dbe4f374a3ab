#include "write/raster_bands.hpp"

#include <algorithm>
#include <cctype>

namespace qtmv::write {

namespace {

constexpr RasterBand kAllBands[] = {RasterBand::fid, RasterBand::boundary, RasterBand::distance};

std::string all_names() {
  std::string names;
  for (const RasterBand band : kAllBands) names += (names.empty() ? "" : ", ") + std::string(raster_band_name(band));
  return names;
}

std::string trimmed_lower(const std::string& text) {
  const std::size_t begin = text.find_first_not_of(" \t");
  if (begin == std::string::npos) return "";
  std::string out = text.substr(begin, text.find_last_not_of(" \t") + 1 - begin);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

}  // namespace

const char* raster_band_name(RasterBand band) {
  switch (band) {
    case RasterBand::fid: return "fid";
    case RasterBand::boundary: return "boundary";
    default: return "distance";
  }
}

const char* raster_band_description(RasterBand band) {
  switch (band) {
    case RasterBand::fid: return "site_fid";
    case RasterBand::boundary: return "boundary";
    default: return "distance_m";
  }
}

std::vector<RasterBand> parse_raster_bands(const std::string& list) {
  std::vector<RasterBand> bands;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = list.find(',', start);
    const std::string name = trimmed_lower(list.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    const auto known = std::find_if(std::begin(kAllBands), std::end(kAllBands),
                                    [&](RasterBand band) { return name == raster_band_name(band); });
    if (known == std::end(kAllBands)) {
      throw WriteError("-bands: '" + list + "': " + (name.empty() ? std::string("a band name is empty") : "'" + name + "' is not a band") +
                       "; name bands from " + all_names() + ", separated by commas");
    }
    if (has_band(bands, *known)) throw WriteError("-bands: '" + list + "': band '" + name + "' named twice");
    bands.push_back(*known);
    if (comma == std::string::npos) return bands;
    start = comma + 1;
  }
}

std::vector<RasterBand> raster_bands(const RasterGrid& grid, bool with_distance) {
  if (grid.bands.empty()) {
    std::vector<RasterBand> bands{RasterBand::fid, RasterBand::boundary};
    if (with_distance) bands.push_back(RasterBand::distance);
    return bands;
  }
  for (std::size_t k = 0; k < grid.bands.size(); ++k) {
    if (std::find(grid.bands.begin(), grid.bands.begin() + k, grid.bands[k]) != grid.bands.begin() + k) {
      throw WriteError(std::string("-bands: band '") + raster_band_name(grid.bands[k]) + "' named twice");
    }
  }
  if (has_band(grid.bands, RasterBand::distance) && !with_distance) {
    throw WriteError("-bands: the distance band asked for, but the labels have no distances");
  }
  return grid.bands;
}

bool has_band(const std::vector<RasterBand>& bands, RasterBand band) {
  return std::find(bands.begin(), bands.end(), band) != bands.end();
}

}  // namespace qtmv::write
