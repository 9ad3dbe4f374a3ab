// VoronoiOptions and VoronoiSummary (src/pipeline/voronoi_options.hpp, plain data without GDAL)
// as Python classes. Each option once, named as the tool's (-level: level, -l: source_layers,
// -oo: open_options, ...); the enums are their command-line words, and a bad word raises
// qtmvoronoi.OptionError with the tool's message.
#include <pybind11/stl.h>

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "bindings.hpp"
#include "common/device_spec.hpp"
#include "pipeline/voronoi_options.hpp"
#include "write/raster_bands.hpp"

namespace qtmv::python {

namespace {

using Layout = write::RasterGrid::Layout;
using Vertices = write::VectorLayers::Vertices;

// A word of the command line and its value.
template <class E>
using Choices = std::vector<std::pair<const char*, E>>;

const Choices<label::Rule> kRules{{"exact", label::Rule::exact}, {"cell", label::Rule::cell}};
const Choices<label::Algorithm> kAlgorithms{
    {"auto", label::Algorithm::automatic}, {"hier", label::Algorithm::hier}, {"brute", label::Algorithm::brute}};
const Choices<OutputKind> kKinds{{"auto", OutputKind::automatic}, {"vector", OutputKind::vector}, {"raster", OutputKind::raster}};
const Choices<Vertices> kVertices{{"auto", Vertices::automatic}, {"corners", Vertices::corners}, {"all", Vertices::all}};
const Choices<Layout> kLayouts{{"qtm", Layout::qtm}, {"lonlat", Layout::lonlat}};
const Choices<sites::EdgeShape> kEdges{{"lonlat", sites::EdgeShape::lonlat}, {"geodesic", sites::EdgeShape::geodesic}};
const Choices<sites::WrapMode> kWraps{{"auto", sites::WrapMode::automatic}, {"none", sites::WrapMode::none}};

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// The value of `word` among `choices`; otherwise OptionError as the tool says it.
template <class E>
E parse(const char* option, const std::string& word, const Choices<E>& choices) {
  const std::string w = lower(word);
  std::string names;
  for (const auto& [name, value] : choices) {
    if (w == name) return value;
    names += (names.empty() ? "" : ", ") + std::string(name);
  }
  raise(exceptions().option_error, std::string(option) + ": '" + word + "' is not one of " + names);
}

template <class E>
std::string word_of(E value, const Choices<E>& choices) {
  for (const auto& [name, v] : choices) {
    if (v == value) return name;
  }
  return "?";
}

// A property of VoronoiOptions that is one of `choices`, at `member` of the options.
template <class E, class Member>
void choice_property(py::class_<VoronoiOptions>& c, const char* name, const char* option, const Choices<E>& choices,
                     Member member, const char* doc) {
  c.def_property(
      name, [member, &choices](const VoronoiOptions& o) { return word_of<E>(member(const_cast<VoronoiOptions&>(o)), choices); },
      [member, option, &choices](VoronoiOptions& o, const std::string& word) { member(o) = parse<E>(option, word, choices); },
      doc);
}

std::vector<std::string> name_values(const char* option, const std::vector<std::string>& items) {
  for (const std::string& item : items) {
    if (item.find('=') == std::string::npos || item.front() == '=') {
      raise(exceptions().option_error, std::string(option) + ": '" + item + "' is not NAME=VALUE");
    }
  }
  return items;
}

void bind_reader_options(py::class_<VoronoiOptions>& c) {
  c.def_property(
       "source_layers", [](const VoronoiOptions& o) { return o.read.layers; },
       [](VoronoiOptions& o, std::vector<std::string> v) { o.read.layers = std::move(v); },
       "-l: the source layers to read (several: composite sites); empty: the first layer")
      .def_property(
          "where", [](const VoronoiOptions& o) { return o.read.where; }, [](VoronoiOptions& o, std::string v) { o.read.where = std::move(v); },
          "-where: an attribute filter (OGR SQL expression)")
      .def_property(
          "sql", [](const VoronoiOptions& o) { return o.read.sql; }, [](VoronoiOptions& o, std::string v) { o.read.sql = std::move(v); },
          "-sql: a statement whose result set is read instead of a layer")
      .def_property(
          "dialect", [](const VoronoiOptions& o) { return o.read.dialect; },
          [](VoronoiOptions& o, std::string v) { o.read.dialect = std::move(v); }, "-dialect: the SQL dialect of sql")
      .def_property(
          "s_srs", [](const VoronoiOptions& o) { return o.read.source_srs; },
          [](VoronoiOptions& o, std::string v) { o.read.source_srs = std::move(v); },
          "-s_srs: the sources' CRS, overriding the layer's (any OGRSpatialReference input)")
      .def_property(
          "open_options", [](const VoronoiOptions& o) { return o.read.open_options; },
          [](VoronoiOptions& o, const std::vector<std::string>& v) { o.read.open_options = name_values("-oo", v); },
          "-oo: the source driver's open options, NAME=VALUE each")
      .def_property(
          "strict", [](const VoronoiOptions& o) { return o.read.strict; }, [](VoronoiOptions& o, bool v) { o.read.strict = v; },
          "-strict: a skipped feature or an invalid polygon is an error")
      .def_property(
          "makevalid", [](const VoronoiOptions& o) { return o.read.make_valid; },
          [](VoronoiOptions& o, bool v) { o.read.make_valid = v; }, "-makevalid: invalid polygons repaired by OGR's MakeValid");
  choice_property(c, "edges", "-edges", kEdges, [](VoronoiOptions& o) -> auto& { return o.read.edges; },
                  "-edges: a segment between two vertices is straight in lon/lat ('lonlat') or a geodesic ('geodesic')");
  choice_property(c, "wrap", "-wrap", kWraps, [](VoronoiOptions& o) -> auto& { return o.read.wrap; },
                  "-wrap: 'auto' joins vertices more than 180 degrees apart across +-180; 'none': flat lon/lat");
}

void bind_labeller_options(py::class_<VoronoiOptions>& c) {
  c.def_property(
       "level",
       [](const VoronoiOptions& o) -> py::object {
         return o.level == VoronoiOptions::kLevelFromOutput ? py::none() : py::object(py::int_(o.level));
       },
       [](VoronoiOptions& o, std::optional<int> level) { o.level = level ? *level : VoronoiOptions::kLevelFromOutput; },
       "-level: the QTM level (0..24); None: 9, or for a lon/lat raster sized by tr or ts the level whose cells are "
       "about four times finer than a pixel")
      .def_property(
          "device", [](const VoronoiOptions& o) { return o.device; },
          [](VoronoiOptions& o, const std::string& v) {
            try {
              parse_device_spec(lower(v));
            } catch (const std::invalid_argument&) {
              raise(exceptions().option_error, "-device: '" + v + "' is not one of " + device_spec_forms());
            }
            o.device = lower(v);
          },
          "-device: auto, cpu, cuda, cuda:N, cuda:N,M,... or cuda:all (the same results on each)")
      .def_property(
          "threads", [](const VoronoiOptions& o) { return o.threads; },
          [](VoronoiOptions& o, int v) {
            if (v < 0) raise(exceptions().option_error, "-threads: '" + std::to_string(v) + "' is not a number of threads");
            o.threads = v;
          },
          "-threads: the CPU threads of every stage; 0: all cores (the results do not depend on it)")
      .def_property(
          "memory_limit", [](const VoronoiOptions& o) { return o.memory_limit_bytes; },
          [](VoronoiOptions& o, std::uint64_t v) { o.memory_limit_bytes = v; },
          "host memory the run's products may take (bytes); 0: 80% of the physical RAM");
  choice_property(c, "distance", "-distance", kRules, [](VoronoiOptions& o) -> auto& { return o.rule; },
                  "-distance: 'exact' (to the sites' geometry) or 'cell' (between cell centres, the seed paper's rule)");
  choice_property(c, "algorithm", "-algorithm", kAlgorithms, [](VoronoiOptions& o) -> auto& { return o.algorithm; },
                  "-algorithm: auto, hier (the pruned tree) or brute (every cell against every candidate)");
}

void bind_output_options(py::class_<VoronoiOptions>& c) {
  c.def_property(
       "format", [](const VoronoiOptions& o) { return o.format; }, [](VoronoiOptions& o, std::string v) { o.format = std::move(v); },
       "-of: the GDAL driver's short name; empty: from the destination's extension")
      .def_property(
          "layers", [](const VoronoiOptions& o) { return o.vector.layers; },
          [](VoronoiOptions& o, std::vector<std::string> v) { o.vector.layers = std::move(v); },
          "-layers: of regions, boundary_cells, voronoi_edges, cells")
      .def_property(
          "dataset_options", [](const VoronoiOptions& o) { return o.vector.dataset_options; },
          [](VoronoiOptions& o, const std::vector<std::string>& v) { o.vector.dataset_options = name_values("-dsco", v); },
          "-dsco: the vector driver's dataset creation options, NAME=VALUE each")
      .def_property(
          "layer_options", [](const VoronoiOptions& o) { return o.vector.layer_options; },
          [](VoronoiOptions& o, const std::vector<std::string>& v) { o.vector.layer_options = name_values("-lco", v); },
          "-lco: the vector driver's layer creation options, NAME=VALUE each")
      .def_property(
          "tr",
          [](const VoronoiOptions& o) -> py::object {
            if (o.raster.x_resolution <= 0) return py::none();
            return py::make_tuple(o.raster.x_resolution, o.raster.y_resolution);
          },
          [](VoronoiOptions& o, std::optional<std::pair<double, double>> v) {
            if (v && !(v->first > 0 && v->second > 0)) raise(exceptions().option_error, "-tr: pixel sizes are positive numbers");
            o.raster.x_resolution = v ? v->first : 0;
            o.raster.y_resolution = v ? v->second : 0;
          },
          "-tr: a lon/lat raster's pixel size (x, y) (degrees); None: from ts or the default")
      .def_property(
          "ts",
          [](const VoronoiOptions& o) -> py::object {
            if (o.raster.width <= 0) return py::none();
            return py::make_tuple(o.raster.width, o.raster.height);
          },
          [](VoronoiOptions& o, std::optional<std::pair<int, int>> v) {
            if (v && !(v->first > 0 && v->second > 0)) raise(exceptions().option_error, "-ts: sizes are positive numbers of pixels");
            o.raster.width = v ? v->first : 0;
            o.raster.height = v ? v->second : 0;
          },
          "-ts: a lon/lat raster's size (width, height) (pixels); None: from tr or the default")
      .def_property(
          "data_type", [](const VoronoiOptions& o) { return o.raster.data_type; },
          [](VoronoiOptions& o, std::string v) { o.raster.data_type = std::move(v); },
          "-ot: the bands' type, Byte, UInt16, Int16, UInt32, Int32, Float32 or Float64; empty: Float32 when every FID is exact in it, else Float64")
      .def_property(
          "creation_options", [](const VoronoiOptions& o) { return o.raster.creation_options; },
          [](VoronoiOptions& o, const std::vector<std::string>& v) { o.raster.creation_options = name_values("-co", v); },
          "-co: the raster driver's creation options, NAME=VALUE each")
      .def_property(
          "bands",
          [](const VoronoiOptions& o) {
            std::vector<std::string> names;
            for (const write::RasterBand band : o.raster.bands) names.emplace_back(write::raster_band_name(band));
            return names;
          },
          [](VoronoiOptions& o, const std::vector<std::string>& names) {
            std::string list;  // -bands' own parser, for its checks and messages
            for (const std::string& name : names) list += (list.empty() ? "" : ",") + name;
            try {
              o.raster.bands = names.empty() ? std::vector<write::RasterBand>{} : write::parse_raster_bands(list);
            } catch (const write::WriteError& e) {
              raise(exceptions().option_error, e.what());
            }
          },
          "-bands: a raster's bands in order, of 'fid', 'boundary', 'distance'; empty: all three")
      .def_readwrite("overwrite", &VoronoiOptions::overwrite, "-overwrite: replace an existing destination")
      .def_readwrite("check_disk_space", &VoronoiOptions::check_disk_space,
                     "refuse, before any work, an output larger than its directory's free space");
  choice_property(c, "output", "output", kKinds, [](VoronoiOptions& o) -> auto& { return o.kind; },
                  "'vector' (as -layers), 'raster' (as -raster) or 'auto' (the driver decides, vector when it writes both)");
  choice_property(c, "vertices", "-vertices", kVertices, [](VoronoiOptions& o) -> auto& { return o.vector.ring_vertices; },
                  "-vertices: the regions' rings keep every cell vertex along parallels ('all', the default of 'auto') or the runs' ends ('corners')");
  choice_property(c, "raster", "-raster", kLayouts, [](VoronoiOptions& o) -> auto& { return o.raster.layout; },
                  "-raster: 'qtm' (one pixel per cell: column j, row octant * 2**level + i) or 'lonlat' (EPSG:4326 over the globe)");
}

void bind_tile_options(py::class_<VoronoiOptions>& c) {
  c.def_property(
       "tile",
       [](const VoronoiOptions& o) -> py::object {
         if (o.tile_count <= 0) return py::none();
         return py::make_tuple(o.tile_index, o.tile_count);
       },
       [](VoronoiOptions& o, std::optional<std::pair<int, int>> v) {
         if (v && !(v->second >= 1 && v->first >= 1 && v->first <= v->second)) {
           raise(exceptions().option_error, "-tile: (" + std::to_string(v->first) + ", " + std::to_string(v->second) +
                                                ") is not (K, N) with N a positive number of tiles and K from 1 to N");
         }
         o.tile_index = v ? v->first : 0;
         o.tile_count = v ? v->second : 0;
       },
       "-tile K/N as (K, N): a tile job, labelling tile K of N and writing its tile product (.qtmt); None: a whole run")
      .def_readwrite("part", &VoronoiOptions::part,
                     "-part: with tile, the tile job writes its part of the output instead of a tile product: of "
                     "vector output a GeoPackage (regions cut at the tile's edges), of a raster a band of its rows "
                     "(a GeoTIFF, say; every site is read)")
      .def_readwrite("merge", &VoronoiOptions::merge,
                     "-merge: tile products (files, or directories of .qtmt files) joined instead of labelling; "
                     "with format 'VRT', parts (directories of .gpkg or .tif files) indexed: an OGR VRT over "
                     "vector parts, a GDAL VRT mosaic over raster parts");
}

py::dict summary_dict(const VoronoiSummary& s) {
  py::dict d;
  d["driver"] = s.driver;
  d["raster"] = s.raster;
  d["features"] = s.features;
  d["sites"] = s.sites;
  d["skipped"] = s.skipped;
  d["invalid_polygons"] = s.invalid_polygons;
  d["repaired_polygons"] = s.repaired_polygons;
  d["level"] = s.level;
  d["cells"] = s.cells;
  d["sites_without_cell"] = s.sites_without_cell;
  d["device"] = s.device;
  d["tile_index"] = s.tile_index;
  d["tile_count"] = s.tile_count;
  d["read_seconds"] = s.read_seconds;
  d["rasterise_seconds"] = s.rasterise_seconds;
  d["prepare_seconds"] = s.prepare_seconds;
  d["label_seconds"] = s.label_seconds;
  d["write_seconds"] = s.write_seconds;
  d["total_seconds"] = s.total_seconds;
  return d;
}

}  // namespace

void bind_options(py::module_& m) {
  py::class_<VoronoiOptions> c(m, "VoronoiOptions", R"(The options of a run, each once, as the tool's (man qtmvoronoi).

VoronoiOptions(**options) sets the attributes named; an unknown name raises TypeError, a bad
value qtmvoronoi.OptionError. The progress callback and the message sink are run_voronoi's
arguments.)");
  c.def(py::init([](const py::kwargs& kwargs) {
          py::object o = py::cast(VoronoiOptions{});
          for (const auto& [name, value] : kwargs) {
            if (!py::hasattr(o, name)) throw py::type_error("VoronoiOptions: no option '" + py::str(name).cast<std::string>() + "'");
            py::setattr(o, name, value);
          }
          return o.cast<VoronoiOptions>();
        }));
  bind_reader_options(c);
  bind_labeller_options(c);
  bind_output_options(c);
  bind_tile_options(c);

  py::class_<VoronoiSummary>(m, "VoronoiSummary", "What a run did: counts, and wall-clock seconds per stage.")
      .def_readonly("driver", &VoronoiSummary::driver, "the GDAL driver written with")
      .def_readonly("raster", &VoronoiSummary::raster, "raster (True) or vector output")
      .def_readonly("features", &VoronoiSummary::features, "features read from the source (after where)")
      .def_readonly("sites", &VoronoiSummary::sites, "features kept as sites")
      .def_readonly("skipped", &VoronoiSummary::skipped, "features skipped (each named in a warning)")
      .def_readonly("invalid_polygons", &VoronoiSummary::invalid_polygons, "features with an invalid polygon")
      .def_readonly("repaired_polygons", &VoronoiSummary::repaired_polygons, "of them, repaired by makevalid")
      .def_readonly("level", &VoronoiSummary::level, "the QTM level")
      .def_readonly("cells", &VoronoiSummary::cells, "8 * 4**level")
      .def_readonly("sites_without_cell", &VoronoiSummary::sites_without_cell, "sites that got no cell")
      .def_readonly("device", &VoronoiSummary::device, "where the labelling ran")
      .def_readonly("tile_index", &VoronoiSummary::tile_index, "a tile job's K (0: a whole run)")
      .def_readonly("tile_count", &VoronoiSummary::tile_count, "a tile job's N (0: a whole run)")
      .def_readonly("read_seconds", &VoronoiSummary::read_seconds, "reading and rasterising the sites (s)")
      .def_readonly("rasterise_seconds", &VoronoiSummary::rasterise_seconds, "of read_seconds, tracing and filling the sites' cells (s)")
      .def_readonly("prepare_seconds", &VoronoiSummary::prepare_seconds, "the labeller's candidates and tree (s)")
      .def_readonly("label_seconds", &VoronoiSummary::label_seconds, "labelling every cell (s)")
      .def_readonly("write_seconds", &VoronoiSummary::write_seconds, "writing the dataset, its close and rename (s)")
      .def_readonly("total_seconds", &VoronoiSummary::total_seconds, "the whole run (s)")
      .def("line", &VoronoiSummary::line, "The tool's closing line: sites, level, cells, device, time per stage.")
      .def("to_dict", &summary_dict, "The summary as a dict of its attributes.")
      .def("__repr__", [](const VoronoiSummary& s) { return "<VoronoiSummary: " + s.line() + ">"; });
}

}  // namespace qtmv::python
