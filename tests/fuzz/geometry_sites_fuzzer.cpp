// WKB or WKT geometry -> site cells: the geometry becomes a one-feature CSV in /vsimem/ and goes
// through the whole reader (read_sites: checks, unwrapping, tracing, polygon fill, claims) at a
// coarse level. A bad geometry may be skipped or refused (ReadError); nothing else may happen.
#include <cpl_vsi.h>
#include <gdal.h>
#include <ogr_geometry.h>

#include <memory>
#include <string>

#include "fuzz_input.hpp"
#include "sites/ogr_site_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool registered = (GDALAllRegister(), CPLSetErrorHandler(CPLQuietErrorHandler), true);
  (void)registered;
  qtmv::fuzz::Input in(data, size);
  const std::uint8_t mode = in.take<std::uint8_t>();
  std::string wkt;
  if (mode & 1) {  // WKB, through OGR's parser
    OGRGeometry* g = nullptr;
    if (OGRGeometryFactory::createFromWkb(in.data(), nullptr, &g, in.size()) != OGRERR_NONE || !g) return 0;
    char* text = nullptr;
    g->exportToWkt(&text);
    wkt = text ? text : "";
    CPLFree(text);
    delete g;
  } else {  // WKT, through the CSV driver's parser
    wkt = in.rest();
    if (wkt.find_first_of("\"\r\n") != std::string::npos) return 0;  // one CSV field
  }
  const std::string path = "/vsimem/geometry_sites_fuzzer.csv";
  const std::string csv = "WKT,n\n\"" + wkt + "\",1\n";
  VSIFCloseL(VSIFileFromMemBuffer(path.c_str(), reinterpret_cast<GByte*>(const_cast<char*>(csv.data())),
                                  csv.size(), FALSE));
  qtmv::sites::ReadOptions options;
  options.level = (mode >> 1) % 7;  // up to 524 288 cells: polygons that cover the globe stay quick
  options.edges = (mode & 0x80) ? qtmv::sites::EdgeShape::geodesic : qtmv::sites::EdgeShape::lonlat;
  try {
    const qtmv::sites::SiteSet sites = qtmv::sites::read_sites(path, options);
    for (const auto& cell : sites.geometry.site_cells) {
      if (!qtmv::grid::is_valid_code(cell.code, options.level)) std::abort();
    }
    for (const auto& cell : sites.geometry.fixed_cells) {
      if (!qtmv::grid::is_valid_code(cell.code, options.level)) std::abort();
    }
    for (const auto& node : sites.geometry.fixed_nodes) {
      if (node.level < 0 || node.level >= options.level || !qtmv::grid::is_valid_code(node.code, node.level)) {
        std::abort();
      }
    }
  } catch (const qtmv::sites::ReadError&) {
  }
  VSIUnlink(path.c_str());
  return 0;
}
