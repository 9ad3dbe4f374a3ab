#include "pipeline/output_format.hpp"

#include <gdal_priv.h>

#include <cctype>
#include <sstream>
#include <string>

#include "pipeline/voronoi_error.hpp"

namespace qtmv {

namespace {

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

OutputFormat choose_output_format(const std::string& destination, const std::string& format, OutputKind kind) {
  GDALAllRegister();
  auto can_vector = [](GDALDriver* d) {
    return d->GetMetadataItem(GDAL_DCAP_VECTOR) && d->GetMetadataItem(GDAL_DCAP_CREATE);
  };
  auto can_raster = [](GDALDriver* d) {
    return d->GetMetadataItem(GDAL_DCAP_RASTER) &&
           (d->GetMetadataItem(GDAL_DCAP_CREATE) || d->GetMetadataItem(GDAL_DCAP_CREATECOPY));
  };
  auto pick = [&](GDALDriver* d) -> OutputFormat {
    const std::string name = d->GetDescription();
    const bool vector = can_vector(d), raster = can_raster(d);
    if (kind == OutputKind::raster) {
      if (!raster) throw VoronoiError("the " + name + " driver cannot write rasters (-raster, -tr, -ts, -co)");
      return {name, true};
    }
    if (kind == OutputKind::vector && !vector) {
      throw VoronoiError("the " + name + " driver cannot write vectors (-layers, -lco, -dsco)");
    }
    if (!vector && !raster) throw VoronoiError("the " + name + " driver cannot create datasets");
    return {name, !vector};
  };

  if (!format.empty()) {
    GDALDriver* driver = GetGDALDriverManager()->GetDriverByName(format.c_str());
    if (!driver) throw VoronoiError("-of " + format + ": no such GDAL driver (--formats lists them)");
    return pick(driver);
  }
  // A connection string (PG:dbname=...) names its driver by its prefix.
  GDALDriverManager* manager = GetGDALDriverManager();
  for (int k = 0; k < manager->GetDriverCount(); ++k) {
    GDALDriver* d = manager->GetDriver(k);
    const char* prefix = d->GetMetadataItem(GDAL_DMD_CONNECTION_PREFIX);
    if (prefix && STARTS_WITH_CI(destination.c_str(), prefix) && (can_vector(d) || can_raster(d))) return pick(d);
  }
  // As GDAL's utilities do: the drivers whose extensions match, in registration order (GTiff
  // before COG); a driver that writes both (GPKG) writes vectors unless told otherwise.
  const std::string name = lower(CPLGetFilename(destination.c_str()));
  GDALDriver* first_vector = nullptr;
  GDALDriver* first_raster = nullptr;
  for (int k = 0; k < manager->GetDriverCount(); ++k) {
    GDALDriver* d = manager->GetDriver(k);
    const char* list = d->GetMetadataItem(GDAL_DMD_EXTENSIONS);
    if (!list) list = d->GetMetadataItem(GDAL_DMD_EXTENSION);
    if (!list) continue;
    std::istringstream extensions{lower(list)};
    bool match = false;
    for (std::string ext; extensions >> ext && !match;) match = ends_with(name, "." + ext);
    if (!match) continue;
    if (!first_vector && can_vector(d)) first_vector = d;
    if (!first_raster && can_raster(d)) first_raster = d;
  }
  GDALDriver* chosen = kind == OutputKind::raster   ? first_raster
                       : kind == OutputKind::vector ? first_vector
                       : first_vector               ? first_vector
                                                    : first_raster;
  if (!chosen) {
    const std::string what = kind == OutputKind::raster ? "raster " : kind == OutputKind::vector ? "vector " : "";
    throw VoronoiError("cannot tell the output format from '" + destination + "': no GDAL " + what +
                       "driver writes files of that extension; use -of FORMAT (--formats lists them)");
  }
  return pick(chosen);
}

bool is_database_driver(const std::string& driver) {
  GDALDriver* d = GetGDALDriverManager()->GetDriverByName(driver.c_str());
  return d && d->GetMetadataItem(GDAL_DMD_CONNECTION_PREFIX) != nullptr;
}

}  // namespace qtmv
