// qtmv_bench: times the labeller (brute or hier, CPU or CUDA) and checks its labels against a
// float64 brute-force reference on a random sample of cells. Core-only: no GDAL.
//
//   qtmv_bench --sites uniform:135000 --level 11,13 --algorithm hier --device cuda --repeat 5
//   qtmv_bench --sites testdata/country_centres.csv --level 5,6,7,8,9 --device cpu --threads 1 --csv
//   qtmv_bench --sites testdata/country_centres.csv --level 10,12 --device cpu --outlines --repeat 9
//
// --outlines times label_outlines (the outline cells and cells per site, what the vector writers
// take) instead of label_cells (every cell's label); the sample is checked through site_of.
//
// Sites: a CSV of lon,lat (degrees; a header line and further columns are allowed),
// uniform:N (N seeded random points, uniform on the sphere), arcs:N (N seeded random
// great-circle arcs of 5 to 25 degrees, cut into pieces of a quarter cell edge as the readers do),
// caps:N (N seeded random polygon sites: regular 36-gons of radius 3 to 15 degrees, their rings as
// arcs and the cells whose centres lie inside them as fixed cells; caps may overlap).
// Several site specs or levels may be given, comma-separated (--sites takes ';' between specs).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <memory>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "grid/qtm.hpp"
#include "common/device_spec.hpp"
#include "common/visible_devices.hpp"
#include "common/host_info.hpp"
#include "common/openmp_threads.hpp"
#include "label/label_engine.hpp"
#include "label/synthetic_sites.hpp"
#include "label/label_cuda.hpp"
#include "label/labeller.hpp"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace {

using namespace qtmv;
using label::Algorithm;
using label::Rule;
using grid::Vec3;

struct Args {
  std::vector<std::string> sites{"uniform:250"};
  std::vector<int> levels{9};
  Algorithm algorithm = Algorithm::hier;
  Rule rule = Rule::exact;
  std::string device = "auto";
  int repeat = 5;
  int threads = 0;
  bool distance = false;
  bool boundary = true;
  std::uint64_t check = 1000000;
  std::uint64_t seed = 1;
  bool csv = false;
  bool csv_header = true;
  bool host_tree = false;  // GPU runs: build hier's tree on the host (the old way) rather than on the GPU
  bool outlines = false;   // label_outlines instead of label_cells
};

[[noreturn]] void usage(const std::string& error) {
  std::cerr << "qtmv_bench: " << error << "\n"
            << "usage: qtmv_bench [--sites SPEC[;SPEC...]] [--level L[,L...]] [--algorithm brute|hier]\n"
               "                  [--rule exact|cell] [--device auto|cpu|cuda|cuda:N] [--repeat R] [--threads T]\n"
               "                  [--distance] [--no-boundary] [--check N] [--seed S] [--csv] [--no-header] [--host-tree]\n"
               "                  [--outlines]\n"
               "  SPEC: FILE.csv (lon,lat per line) | uniform:N | arcs:N | caps:N\n";
  std::exit(2);
}

std::vector<std::string> split(const std::string& text, char sep) {
  std::vector<std::string> parts;
  std::stringstream in(text);
  std::string part;
  while (std::getline(in, part, sep)) {
    if (!part.empty()) parts.push_back(part);
  }
  return parts;
}

Args parse(int argc, char** argv) {
  Args a;
  for (int k = 1; k < argc; ++k) {
    const std::string opt = argv[k];
    auto value = [&]() -> std::string {
      if (k + 1 >= argc) usage(opt + " needs a value");
      return argv[++k];
    };
    if (opt == "--sites") {
      a.sites = split(value(), ';');
    } else if (opt == "--level") {
      a.levels.clear();
      for (const std::string& l : split(value(), ',')) a.levels.push_back(std::stoi(l));
    } else if (opt == "--algorithm") {
      const std::string v = value();
      if (v != "brute" && v != "hier") usage("--algorithm is brute or hier");
      a.algorithm = v == "brute" ? Algorithm::brute : Algorithm::hier;
    } else if (opt == "--rule" || opt == "--distance-rule") {
      const std::string v = value();
      if (v != "exact" && v != "cell") usage("--rule is exact or cell");
      a.rule = v == "cell" ? Rule::cell : Rule::exact;
    } else if (opt == "--device") {
      a.device = value();
    } else if (opt == "--repeat") {
      a.repeat = std::max(1, std::stoi(value()));
    } else if (opt == "--threads") {
      a.threads = std::stoi(value());
    } else if (opt == "--distance") {
      a.distance = true;
    } else if (opt == "--no-boundary") {
      a.boundary = false;
    } else if (opt == "--check") {
      a.check = std::stoull(value());
    } else if (opt == "--seed") {
      a.seed = std::stoull(value());
    } else if (opt == "--csv") {
      a.csv = true;
    } else if (opt == "--host-tree") {
      a.host_tree = true;
    } else if (opt == "--outlines") {
      a.outlines = true;
    } else if (opt == "--no-header") {
      a.csv_header = false;
    } else {
      usage("unknown option " + opt);
    }
  }
  return a;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

/// A polygon site for caps:N: a regular spherical polygon of kCapSides great-circle edges on the
/// circle of angular radius `radius` (radians) about the unit vector c, its edges cut into pieces
/// as the readers cut rings, and the cells whose centres lie inside it as fixed cells (found by
/// descending the quadtrees: node_radius bounds each node).
constexpr int kCapSides = 36;
void add_cap(label::SiteGeometry& g, const Vec3& c, double radius, std::int32_t site) {
  // An orthonormal frame (e1, e2) about c, and the vertices counter-clockwise seen from outside.
  const Vec3 helper = std::fabs(c.z) < 0.9 ? Vec3{0, 0, 1} : Vec3{1, 0, 0};
  Vec3 e1 = grid::cross(helper, c);
  const double n1 = std::sqrt(grid::dot(e1, e1));
  e1 = {e1.x / n1, e1.y / n1, e1.z / n1};
  const Vec3 e2 = grid::cross(c, e1);
  std::vector<Vec3> v(kCapSides);
  for (int k = 0; k < kCapSides; ++k) {
    const double t = 2 * grid::kPi * k / kCapSides;
    const double a = std::cos(radius), b = std::sin(radius) * std::cos(t), d = std::sin(radius) * std::sin(t);
    v[k] = {a * c.x + b * e1.x + d * e2.x, a * c.y + b * e1.y + d * e2.y, a * c.z + b * e1.z + d * e2.z};
  }
  auto lon = [](const Vec3& p) { return std::atan2(p.y, p.x) / grid::kDegree; };
  auto lat = [](const Vec3& p) { return std::asin(std::max(-1.0, std::min(1.0, p.z))) / grid::kDegree; };
  std::vector<Vec3> normal(kCapSides);  // x is inside when dot(x, normal) > 0 for every edge
  for (int k = 0; k < kCapSides; ++k) {
    const Vec3& p = v[k];
    const Vec3& q = v[(k + 1) % kCapSides];
    label::add_arc(g, lon(p), lat(p), lon(q), lat(q), site);
    normal[k] = grid::cross(p, q);
    if (grid::dot(normal[k], c) < 0) normal[k] = {-normal[k].x, -normal[k].y, -normal[k].z};
  }
  // The inscribed circle's angular radius: tan r_in = tan r cos(pi / sides).
  const double inscribed = std::atan(std::tan(radius) * std::cos(grid::kPi / kCapSides));
  const int level = g.level;
  auto inside = [&](const Vec3& x) {
    for (const Vec3& n : normal) {
      if (grid::dot(x, n) <= 0) return false;
    }
    return true;
  };
  auto angle_to_centre = [&](const Vec3& x) { return std::acos(std::max(-1.0, std::min(1.0, grid::dot(x, c)))); };
  // Depth-first over the quadtrees: a node wholly inside the inscribed circle gives all its cells.
  std::vector<std::pair<grid::Cell, int>> stack;
  for (int o = 0; o < grid::kOctants; ++o) stack.push_back({grid::Cell{o, 0, 0}, 0});
  while (!stack.empty()) {
    const auto [cell, l] = stack.back();
    stack.pop_back();
    const Vec3 p = grid::cell_centre_vector(grid::code_of(cell, l), l);
    const double angle = angle_to_centre(p), r = l == level ? 0.0 : label::node_radius(l, cell);
    if (angle > radius + r + 1e-9) continue;
    if (l == level) {
      if (inside(p)) label::add_fixed_cell(g, grid::code_of(cell, l), site);
      continue;
    }
    if (angle + r < inscribed - 1e-9) {
      const int k = level - l;
      for (std::uint32_t m = 0; m < (std::uint32_t{1} << (2 * k)); ++m) {
        label::add_fixed_cell(g, grid::code_of(grid::descendant(cell, k, m), level), site);
      }
      continue;
    }
    grid::Cell kids[4];
    grid::children(cell, kids);
    for (const grid::Cell& kid : kids) stack.push_back({kid, l + 1});
  }
}

label::SiteGeometry make_sites(const std::string& spec, int level, std::uint64_t seed) {
  label::SiteGeometry g;
  g.level = level;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> lon(-180, 180), z(-1, 1);
  auto random_lat = [&]() { return std::asin(z(rng)) / grid::kDegree; };
  if (spec.rfind("uniform:", 0) == 0) {
    const long n = std::stol(spec.substr(8));
    for (long k = 0; k < n; ++k) {
      const double lo = lon(rng);
      label::add_point(g, lo, random_lat(), static_cast<std::int32_t>(k));
    }
  } else if (spec.rfind("arcs:", 0) == 0) {
    const long n = std::stol(spec.substr(5));
    std::uniform_real_distribution<double> length(5, 25);
    std::normal_distribution<double> normal;
    for (long k = 0; k < n; ++k) {
      // A random start and a random direction; the end is `length` degrees along the great circle.
      const double lo = lon(rng), la = random_lat();
      const Vec3 a = grid::unit_vector(lo, la);
      Vec3 t{normal(rng), normal(rng), normal(rng)};
      const double d = grid::dot(t, a);
      t = {t.x - d * a.x, t.y - d * a.y, t.z - d * a.z};
      const double tn = std::sqrt(grid::dot(t, t));
      const double ang = length(rng) * grid::kDegree;
      const Vec3 b{std::cos(ang) * a.x + std::sin(ang) * t.x / tn, std::cos(ang) * a.y + std::sin(ang) * t.y / tn,
                   std::cos(ang) * a.z + std::sin(ang) * t.z / tn};
      label::add_arc(g, lo, la, std::atan2(b.y, b.x) / grid::kDegree,
                     std::asin(std::max(-1.0, std::min(1.0, b.z))) / grid::kDegree, static_cast<std::int32_t>(k));
    }
  } else if (spec.rfind("caps:", 0) == 0) {
    const long n = std::stol(spec.substr(5));
    std::uniform_real_distribution<double> radius(3, 15);
    for (long k = 0; k < n; ++k) {
      const double lo = lon(rng), la = random_lat();
      add_cap(g, grid::unit_vector(lo, la), radius(rng) * grid::kDegree, static_cast<std::int32_t>(k));
    }
  } else {
    std::ifstream in(spec);
    if (!in) throw std::runtime_error("cannot open site file " + spec);
    std::string line;
    std::int32_t id = 0;
    while (std::getline(in, line)) {
      const std::vector<std::string> f = split(line, ',');
      if (f.size() < 2) continue;
      char* end1 = nullptr;
      char* end2 = nullptr;
      const double lo = std::strtod(f[0].c_str(), &end1), la = std::strtod(f[1].c_str(), &end2);
      if (end1 == f[0].c_str() || end2 == f[1].c_str()) continue;  // a header
      label::add_point(g, lo, la, id++);
    }
    if (id == 0) throw std::runtime_error("no lon,lat rows in " + spec);
  }
  return g;
}

struct Row {
  std::string sites_spec;
  std::size_t sites = 0, pieces = 0, site_cells = 0;
  int level = 0;
  std::uint64_t cells = 0;
  std::string algorithm, rule, device;
  int threads = 0;
  double prepare_ms = 0, label_ms = 0, copy_ms = 0;
  double mean_candidates = 0;
  std::size_t tree_nodes = 0, memory_bytes = 0;
  std::uint64_t checked = 0, mismatches = 0;
  int repeat = 0;
};

void print_header(bool csv) {
  if (csv) {
    std::cout << "sites_spec,sites,pieces,site_cells,level,cells,algorithm,rule,device,threads,repeat,prepare_ms,"
                 "label_ms,copy_ms,cells_per_s,mean_candidates,tree_nodes,memory_bytes,checked,mismatches\n";
  } else {
    std::printf("%-22s %7s %5s %12s %6s %5s %-28s %11s %11s %10s %10s %9s %9s %10s %9s\n", "sites", "n", "level",
                "cells", "algo", "rule", "device", "prepare_ms", "label_ms", "copy_ms", "Gcells/s", "cand/cell",
                "mem_MiB", "checked", "mismatch");
  }
}

void print_row(const Row& r, bool csv) {
  const double rate = r.label_ms > 0 ? r.cells / (r.label_ms / 1e3) : 0;
  if (csv) {
    std::printf("%s,%zu,%zu,%zu,%d,%llu,%s,%s,\"%s\",%d,%d,%.4f,%.4f,%.4f,%.6g,%.4f,%zu,%zu,%llu,%llu\n",
                r.sites_spec.c_str(), r.sites, r.pieces, r.site_cells, r.level, (unsigned long long)r.cells,
                r.algorithm.c_str(), r.rule.c_str(), r.device.c_str(), r.threads, r.repeat, r.prepare_ms, r.label_ms,
                r.copy_ms, rate, r.mean_candidates, r.tree_nodes, r.memory_bytes, (unsigned long long)r.checked,
                (unsigned long long)r.mismatches);
  } else {
    std::printf("%-22s %7zu %5d %12llu %6s %5s %-28s %11.3f %11.3f %10.3f %10.3f %9.2f %9.1f %10llu %9llu\n",
                r.sites_spec.substr(0, 22).c_str(), r.sites, r.level, (unsigned long long)r.cells,
                r.algorithm.c_str(), r.rule.c_str(), r.device.substr(0, 28).c_str(), r.prepare_ms, r.label_ms,
                r.copy_ms, rate / 1e9, r.mean_candidates, r.memory_bytes / 1048576.0, (unsigned long long)r.checked,
                (unsigned long long)r.mismatches);
  }
  std::fflush(stdout);
}

/// The sample of codes to check: all codes when few, else `n` seeded random ones.
std::vector<grid::Code> sample_codes(std::uint64_t cells, std::uint64_t n, std::uint64_t seed) {
  std::vector<grid::Code> codes;
  if (n >= cells) {
    codes.resize(cells);
    for (std::uint64_t k = 0; k < cells; ++k) codes[k] = k;
    return codes;
  }
  std::mt19937_64 rng(seed ^ 0x9e3779b97f4a7c15ull);
  std::uniform_int_distribution<grid::Code> pick(0, cells - 1);
  codes.resize(n);
  for (auto& c : codes) c = pick(rng);
  std::sort(codes.begin(), codes.end());
  return codes;
}

/// Reference labels of the sample: float64 brute force, on a GPU when there is one (it is
/// the same arithmetic), else on all CPU cores.
std::vector<std::int32_t> reference(const std::vector<label::Piece>& candidates, int level,
                                    const std::vector<grid::Code>& codes) {
  if (label::cuda_device_count() > 0) {
    label::cuda::Labeller gpu(0, candidates, nullptr, level);
    return gpu.brute_sites(codes);
  }
  std::vector<std::int32_t> sites(codes.size());
  const std::int64_t n = static_cast<std::int64_t>(codes.size());
#pragma omp parallel for schedule(dynamic, 256)
  for (std::int64_t k = 0; k < n; ++k) sites[k] = label::reference_best(candidates, codes[k], level).site;
  return sites;
}

/// The repetitions' times (ms), for their medians.
struct Timings {
  std::vector<double> prepare, labelling, copying;
};

// Each timer below runs a.repeat times, adds the times to `t`, fills the row's device, tree and
// memory fields, and puts the last run's labels of the sample `codes` into `got`.

// The vector writers' products, on the CPU or a GPU, as the tool asks for them.
void time_outlines(const Args& a, const label::LabelInput& input, const label::LabelOptions& options,
                   const std::vector<grid::Code>& codes, Row& row, Timings& t, std::vector<std::int32_t>& got) {
  row.algorithm += "-outlines";
  for (int r = 0; r < a.repeat; ++r) {
    label::Outlines outlines;
    const label::LabelStats stats = label::label_outlines(input, options, &outlines);
    t.prepare.push_back(stats.prepare_seconds * 1e3);
    t.labelling.push_back(stats.label_seconds * 1e3);
    t.copying.push_back(stats.copy_seconds * 1e3);
    row.device = stats.device;
    row.mean_candidates = stats.mean_candidates;
    row.tree_nodes = stats.tree_nodes;
    if (r + 1 == a.repeat) {
      for (std::size_t k = 0; k < codes.size(); ++k) got[k] = label::site_of(outlines.cells, codes[k]);
    }
  }
  row.threads = thread_count(a.threads);
}

// The whole labeller as a caller sees it, tile by tile; the sample is gathered in the sink.
void time_label_cells(const Args& a, const label::LabelInput& input, const label::LabelOptions& options, int level,
                      const std::vector<grid::Code>& codes, Row& row, Timings& t, std::vector<std::int32_t>& got) {
  for (int r = 0; r < a.repeat; ++r) {
    std::size_t next = 0;
    const label::LabelStats stats = label::label_cells(input, options, [&](const label::LabelTile& tile) {
      while (next < codes.size() && codes[next] < tile.first + tile.count) {
        got[next] = tile.site[codes[next] - tile.first];
        ++next;
      }
    });
    t.prepare.push_back(stats.prepare_seconds * 1e3);
    t.labelling.push_back(stats.label_seconds * 1e3);
    row.device = stats.device;
    row.mean_candidates = stats.mean_candidates;
    row.tree_nodes = stats.tree_nodes;
  }
#ifdef _OPENMP
  row.threads = a.threads > 0 ? a.threads : omp_get_max_threads();
#else
  row.threads = 1;
#endif
  const label::MemoryEstimate need = label::estimate_output_memory(level, options);
  row.memory_bytes = need.output_bytes + row.tree_nodes * sizeof(label::TreeNode);
}

// The GPU directly, so that the labels can stay on the device between repetitions.
void time_gpu(const Args& a, const label::LabelInput& input, const label::LabelOptions& options, int level, int device,
              const std::vector<grid::Code>& codes, Row& row, Timings& t, std::vector<std::int32_t>& got) {
  if (device < 0 || label::cuda_device_count() <= device) throw std::runtime_error("no CUDA device " + a.device);
  const label::cuda::DeviceInfo info = label::cuda::device_info(device);
  row.device = cuda_device_name(device) + " " + info.name;
  std::vector<label::Piece> candidates;
  label::Tree tree;
  const bool hier = a.algorithm == Algorithm::hier;
  const bool device_tree = hier && !a.host_tree;
  if (hier && a.host_tree) row.algorithm = "hier-host-tree";
  std::unique_ptr<label::cuda::Labeller> built;
  for (int r = 0; r < a.repeat; ++r) {
    built.reset();
    const double t0 = now_seconds();
    if (device_tree && a.rule == Rule::exact) {
      // As label_cells does: the input to the GPU, the fixed cells ordered, the candidates and
      // the tree made there (the constructor synchronises).
      built = std::make_unique<label::cuda::Labeller>(device, input, a.distance, a.threads);
      t.prepare.push_back((now_seconds() - t0) * 1e3);
      continue;
    }
    candidates = label::make_candidates(input, a.rule, a.threads);
    if (device_tree) {
      built = std::make_unique<label::cuda::Labeller>(device, candidates, level, a.distance, a.threads);
    } else if (hier) {
      tree = label::build_tree(candidates, level, a.distance, a.threads);
    }
    t.prepare.push_back((now_seconds() - t0) * 1e3);
  }
  if (device_tree) {
    row.mean_candidates = built->tree_info().mean_candidates;
    row.tree_nodes = built->tree_info().nodes;
  } else {
    row.mean_candidates = hier ? tree.mean_candidates : double(candidates.size());
    row.tree_nodes = tree.nodes.size();
    built = std::make_unique<label::cuda::Labeller>(device, candidates, hier ? &tree : nullptr, level);
  }
  label::cuda::Labeller& gpu = *built;
  const label::MemoryEstimate need = label::estimate_output_memory(level, options);
  const std::uint64_t tile =
      std::min<std::uint64_t>(row.cells, static_cast<std::uint64_t>(label::cuda::device_info(device).free_bytes * 0.85) /
                                             need.bytes_per_cell);
  gpu.reserve(tile, a.distance, a.boundary);
  row.memory_bytes = gpu.device_bytes();
  std::vector<std::int32_t> host(std::min<std::uint64_t>(tile, std::uint64_t{1} << 28));
  // One untimed warm-up run, then the timed ones; the last one also brings the sample home.
  gpu.run(0, std::min<std::uint64_t>(tile, row.cells), a.distance, a.boundary);
  for (int r = 0; r < a.repeat; ++r) {
    double ms = 0, copy_ms = 0;
    std::size_t next = 0;
    for (std::uint64_t first = 0; first < row.cells; first += tile) {
      const std::uint64_t count = std::min(tile, row.cells - first);
      ms += gpu.run(first, count, a.distance, a.boundary);
      if (r + 1 == a.repeat) {
        for (std::uint64_t offset = 0; offset < count; offset += host.size()) {
          const std::uint64_t part = std::min<std::uint64_t>(host.size(), count - offset);
          // All outputs come home, as a caller would take them; the sample reads the labels.
          std::vector<float> metres(a.distance ? part : 0);
          std::vector<std::uint8_t> flags(a.boundary ? part : 0);
          copy_ms += gpu.download(offset, part, host.data(), a.distance ? metres.data() : nullptr,
                                  a.boundary ? flags.data() : nullptr);
          const grid::Code base = first + offset;
          while (next < codes.size() && codes[next] < base + part) {
            got[next] = host[codes[next] - base];
            ++next;
          }
        }
      }
    }
    t.labelling.push_back(ms);
    if (r + 1 == a.repeat) t.copying.push_back(copy_ms);
  }
  row.threads = 0;
}

Row run_one(const Args& a, const std::string& spec, int level) {
  const label::SiteGeometry g = make_sites(spec, level, a.seed);
  const label::LabelInput input = g.input();
  label::LabelOptions options;
  options.rule = a.rule;
  options.algorithm = a.algorithm;
  options.device = a.device;
  options.want_distance = a.distance;
  options.want_boundary = a.boundary;
  options.threads = a.threads;

  Row row;
  row.sites_spec = spec;
  row.sites = static_cast<std::size_t>(g.site_count);
  row.pieces = g.pieces.size();
  row.site_cells = g.site_cells.size();
  row.level = level;
  row.cells = grid::cell_count(level);
  row.algorithm = a.algorithm == Algorithm::hier ? "hier" : "brute";
  row.rule = a.rule == Rule::exact ? "exact" : "cell";
  row.repeat = a.repeat;
  const std::vector<grid::Code> codes = sample_codes(row.cells, a.check, a.seed + level);
  std::vector<std::int32_t> got(codes.size());
  Timings t;

  const DeviceSpec device_spec = parse_device_spec(a.device);
  const bool cuda = device_spec.kind == DeviceSpec::Kind::cuda ||
                    (device_spec.kind == DeviceSpec::Kind::automatic && label::cuda_device_count() > 0);
  if (a.outlines) {
    time_outlines(a, input, options, codes, row, t, got);
  } else if (!cuda) {
    time_label_cells(a, input, options, level, codes, row, t, got);
  } else {
    time_gpu(a, input, options, level, cuda_ordinal(device_spec.index), codes, row, t, got);
  }
  row.prepare_ms = median(t.prepare);
  row.label_ms = median(t.labelling);
  row.copy_ms = median(t.copying);

  const std::vector<std::int32_t> want = reference(label::make_candidates(input, a.rule), level, codes);
  row.checked = codes.size();
  for (std::size_t k = 0; k < codes.size(); ++k) row.mismatches += got[k] != want[k];
  return row;
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = parse(argc, argv);
  // As qtmvoronoi: CUDA starts only the devices asked for (common/visible_devices.hpp).
  restrict_visible_devices(a.device);
  try {
    if (!a.csv || a.csv_header) print_header(a.csv);
    std::uint64_t mismatches = 0;
    for (const std::string& spec : a.sites) {
      for (const int level : a.levels) {
        const Row row = run_one(a, spec, level);
        mismatches += row.mismatches;
        print_row(row, a.csv);
      }
    }
    if (mismatches) {
      std::cerr << "qtmv_bench: " << mismatches << " labels differ from the float64 reference\n";
      return 1;
    }
  } catch (const std::exception& e) {
    std::cerr << "qtmv_bench: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
