// The readers' benchmark: reading and rasterising sites at a level. Wall time of read_sites,
// median of several runs.
//
//   sites_bench [--level L] [--points N] [--repeat R] [--threads T] [--edges lonlat|geodesic]
//               [--s_srs SRS] [--sql SQL] [--makevalid] [--messages] [--oo NAME=VALUE]... [LINES_DATASET [LAYER]]
//
// --threads T: threads that trace and fill the sites (0, the default: all).
// --s_srs, --sql, --makevalid, --oo NAME=VALUE: as qtmvoronoi's -s_srs, -sql, -makevalid, -oo
// (a CSV's -oo X_POSSIBLE_NAMES=lon, say); --messages prints the reader's messages (stderr). The digest printed covers every array, the site table's
// counts, the summary's counts and the messages: the same for any thread count, and from build to
// build while the reader's output stays the same.
//
// --points N: N points spread uniformly over the sphere (seeded), written to a temporary
// GeoPackage first (not timed). LINES_DATASET: any OGR dataset, e.g. the Natural Earth 50m
// coastlines:
//   npm pack world-atlas && tar xzf world-atlas-2.0.2.tgz
//   ogr2ogr -f GPKG coast50.gpkg package/land-50m.json land -a_srs EPSG:4326
//           -explodecollections -nlt MULTILINESTRING -nln coastlines   (one line)
#include <gdal_priv.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "sites/ogr_site_reader.hpp"

namespace {

std::string make_points(int count) {
  const std::string path = "/tmp/qtmv_sites_bench_points_" + std::to_string(count) + ".gpkg";
  GDALAllRegister();
  VSIUnlink(path.c_str());
  GDALDatasetUniquePtr ds(
      GetGDALDriverManager()->GetDriverByName("GPKG")->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  OGRSpatialReference srs;
  srs.importFromEPSG(4326);
  OGRLayer* layer = ds->CreateLayer("points", &srs, wkbPoint, nullptr);
  OGRFieldDefn field("name", OFTString);
  if (layer->CreateField(&field) != OGRERR_NONE) throw std::runtime_error("cannot write " + path);
  std::mt19937_64 random(12345);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  if (layer->StartTransaction() != OGRERR_NONE) throw std::runtime_error("cannot write " + path);
  for (int k = 0; k < count; ++k) {
    const double lon = 180.0 * uniform(random), lat = std::asin(uniform(random)) * 180.0 / M_PI;
    OGRFeatureUniquePtr f(OGRFeature::CreateFeature(layer->GetLayerDefn()));
    f->SetField("name", ("p" + std::to_string(k)).c_str());
    f->SetGeometryDirectly(new OGRPoint(lon, lat));
    if (layer->CreateFeature(f.get()) != OGRERR_NONE) throw std::runtime_error("cannot write " + path);
  }
  if (layer->CommitTransaction() != OGRERR_NONE) throw std::runtime_error("cannot write " + path);
  return path;
}

/// FNV-1a over plain values: a digest of what a read gave, to compare builds and thread counts.
struct Digest {
  std::uint64_t h = 1469598103934665603ull;
  template <class T>
  void add(const T& v) {
    unsigned char bytes[sizeof(T)];
    std::memcpy(bytes, &v, sizeof(T));
    for (unsigned char b : bytes) h = (h ^ b) * 1099511628211ull;
  }
  void add_text(const std::string& text) {
    for (unsigned char b : text) h = (h ^ b) * 1099511628211ull;
    add(text.size());
  }
};

/// The digest of every array, the site table's counts, the summary's counts and the messages.
std::uint64_t digest_of(const qtmv::sites::SiteSet& set, const std::vector<std::string>& messages) {
  Digest d;
  const qtmv::label::SiteGeometry& g = set.geometry;
  d.add(g.site_count);
  for (const auto& p : g.pieces) {
    d.add(p.a), d.add(p.b), d.add(p.site);
  }
  for (const auto& c : g.site_cells) {
    d.add(c.code), d.add(c.site), d.add(c.piece_begin), d.add(c.piece_end);
  }
  for (const auto& c : g.fixed_cells) d.add(c.code), d.add(c.site);
  for (const auto& n : g.fixed_nodes) d.add(n.code), d.add(n.level), d.add(n.site);
  for (const auto& r : set.table.sites) {
    d.add(r.fid), d.add(r.kind), d.add(r.site_cells), d.add(r.fixed_cells), d.add(r.has_own_cell), d.add(r.layer);
  }
  const qtmv::sites::ReadSummary& s = set.summary;
  for (std::uint64_t v : {s.features, s.sites, s.skipped, s.skipped_empty, s.skipped_type, s.skipped_coordinate,
                          s.skipped_transform, s.skipped_unreadable, s.invalid_polygons, s.repaired_polygons,
                          s.sites_without_own_cell, s.vertex_steps, s.wrapped_features}) {
    d.add(v);
  }
  for (const std::string& m : messages) {
    if (m.rfind("trace:", 0) != 0) d.add_text(m);
  }
  return d.h;
}

double median_seconds(const std::string& path, qtmv::sites::ReadOptions options, int repeat,
                      qtmv::sites::ReadSummary* summary, std::size_t* pieces, std::size_t* site_cells,
                      std::size_t* fixed_cells, std::size_t* fixed_nodes, std::uint64_t* digest,
                      bool print_messages) {
  std::vector<double> seconds;
  for (int r = 0; r < repeat; ++r) {
    std::vector<std::string> messages;
    options.messages = [&messages](qtmv::Severity, const std::string& m) { messages.push_back(m); };
    const auto start = std::chrono::steady_clock::now();
    const qtmv::sites::SiteSet set = qtmv::sites::read_sites(path, options);
    seconds.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    *summary = set.summary;
    *pieces = set.geometry.pieces.size();
    *site_cells = set.geometry.site_cells.size();
    *fixed_cells = set.geometry.fixed_cells.size();
    *fixed_nodes = set.geometry.fixed_nodes.size();
    *digest = digest_of(set, messages);
    if (print_messages) {
      for (const std::string& m : messages) std::fprintf(stderr, "%s\n", m.c_str());
    }
  }
  std::sort(seconds.begin(), seconds.end());
  return seconds[seconds.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  qtmv::sites::ReadOptions options;
  options.level = 12;
  int points = 135000, repeat = 5;
  std::string lines, layer;
  bool print_messages = false;
  for (int k = 1; k < argc; ++k) {
    const std::string a = argv[k];
    if (a == "--level" && k + 1 < argc) options.level = std::atoi(argv[++k]);
    else if (a == "--points" && k + 1 < argc) points = std::atoi(argv[++k]);
    else if (a == "--repeat" && k + 1 < argc) repeat = std::max(1, std::atoi(argv[++k]));
    else if (a == "--threads" && k + 1 < argc) options.threads = std::atoi(argv[++k]);
    else if (a == "--edges" && k + 1 < argc) options.edges = qtmv::sites::parse_edge_shape(argv[++k]);
    else if (a == "--s_srs" && k + 1 < argc) options.source_srs = argv[++k];
    else if (a == "--sql" && k + 1 < argc) options.sql = argv[++k];
    else if (a == "--makevalid") options.make_valid = true;
    else if (a == "--messages") print_messages = true;
    else if (a == "--oo" && k + 1 < argc) options.open_options.push_back(argv[++k]);
    else if (lines.empty()) lines = a;
    else layer = a;
  }
  try {
    qtmv::sites::ReadSummary summary;
    std::size_t pieces = 0, site_cells = 0, fixed_cells = 0, fixed_nodes = 0;
    std::uint64_t digest = 0;
    if (points > 0) {
      const std::string path = make_points(points);
      const double s =
          median_seconds(path, options, repeat, &summary, &pieces, &site_cells, &fixed_cells, &fixed_nodes, &digest, print_messages);
      std::printf("points     level %d: %llu sites, %zu site cells: median %.3f s of %d runs\n", options.level,
                  static_cast<unsigned long long>(summary.sites), site_cells, s, repeat);
      VSIUnlink(path.c_str());
    }
    if (!lines.empty()) {
      if (!layer.empty()) options.layers = {layer};
      const double s =
          median_seconds(lines, options, repeat, &summary, &pieces, &site_cells, &fixed_cells, &fixed_nodes, &digest, print_messages);
      std::printf("dataset    level %d, %d thread(s): %llu sites, %zu pieces, %zu site cells, %zu fixed cells, %zu "
                  "fixed nodes: median %.3f s of %d runs; digest %016llx\n",
                  options.level, options.threads, static_cast<unsigned long long>(summary.sites), pieces, site_cells,
                  fixed_cells, fixed_nodes, s, repeat, static_cast<unsigned long long>(digest));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "sites_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
