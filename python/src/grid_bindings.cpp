// The grid's functions (src/grid/, header-only) over numpy arrays, as h3-py's numpy API: each
// takes arrays (or scalars) and returns arrays of their shape, looping in C++ with the GIL
// released; one code, one position or one cell in gives Python scalars out. Exactly the C++
// results: these call the library's functions, nothing is re-implemented.
#include <pybind11/numpy.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "bindings.hpp"
#include "grid/qtm.hpp"
#include "grid/qtm_checks.hpp"

namespace qtmv::python {

namespace {

template <class T>
using Array = py::array_t<T, py::array::c_style | py::array::forcecast>;
using Shape = std::vector<py::ssize_t>;

Shape shape_of(const py::array& a) { return Shape(a.shape(), a.shape() + a.ndim()); }

Shape with_tail(Shape shape, std::initializer_list<py::ssize_t> tail) {
  shape.insert(shape.end(), tail);
  return shape;
}

// A 0-d result (one code or position in) as a Python scalar, else the array.
py::object finish(const py::array& a) { return a.ndim() == 0 ? a.attr("item")() : py::object(a); }

// The arguments broadcast against each other (numpy's rules).
template <class... Arrays>
std::vector<py::array> broadcast(const Arrays&... arrays) {
  const py::object b = py::module_::import("numpy").attr("broadcast_arrays")(arrays...);
  std::vector<py::array> out;
  for (const py::handle h : b) out.push_back(py::reinterpret_borrow<py::array>(h));
  return out;
}

Array<double> doubles(const py::handle& h, const char* name) {
  const py::array a = py::reinterpret_borrow<py::array>(h);
  const char kind = a.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') throw py::type_error(std::string(name) + ": not numbers (dtype " + py::str(a.dtype()).cast<std::string>() + ")");
  return Array<double>::ensure(a);
}

// Integers as int64 (signed input) or uint64; floats are refused (codes are exact integers).
py::array integers(const py::object& values, const char* name) {
  py::array a = py::array::ensure(values);
  if (!a) throw py::type_error(std::string(name) + ": not an array of integers");
  const char kind = a.dtype().kind();
  if (kind == 'u') return Array<std::uint64_t>::ensure(a);
  if (kind == 'i' || kind == 'b') return Array<std::int64_t>::ensure(a);
  throw py::type_error(std::string(name) + ": not integers (dtype " + py::str(a.dtype()).cast<std::string>() + ")");
}

// The codes of `values` as uint64, each a cell of `level`; otherwise the first that is not
// raises ValueError with the library's message, naming its (flat) index.
Array<grid::Code> codes_of(const py::object& values, int level) {
  grid::require_level(level);
  const py::array a = integers(values, "codes");
  const py::ssize_t n = a.size();
  const grid::Code count = grid::cell_count(level);
  py::ssize_t bad = -1;
  std::int64_t negative = 0;
  if (a.dtype().kind() != 'u') {
    const auto* v = static_cast<const std::int64_t*>(a.data());
    py::gil_scoped_release release;
    for (py::ssize_t k = 0; k < n && bad < 0; ++k) {
      if (v[k] < 0 || static_cast<grid::Code>(v[k]) >= count) bad = k, negative = v[k];
    }
  } else {
    const auto* v = static_cast<const grid::Code*>(a.data());
    py::gil_scoped_release release;
    for (py::ssize_t k = 0; k < n && bad < 0; ++k) {
      if (v[k] >= count) bad = k;
    }
  }
  if (bad >= 0) {
    const std::string where = n == 1 && a.ndim() == 0 ? "" : "codes[" + std::to_string(bad) + "]: ";
    if (negative < 0) throw std::invalid_argument(where + "QTM code " + std::to_string(negative) + " is not a code: codes are not negative");
    try {
      grid::require_code(static_cast<const grid::Code*>(a.data())[bad], level);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(where + e.what());
    }
  }
  return Array<grid::Code>::ensure(a);
}

// Runs body(k) for every k of [0, n) with the GIL released.
template <class Body>
void each(py::ssize_t n, Body body) {
  py::gil_scoped_release release;
  for (py::ssize_t k = 0; k < n; ++k) body(k);
}

py::object lonlat_to_code(const py::object& lon, const py::object& lat, int level) {
  grid::require_level(level);
  const std::vector<py::array> b = broadcast(lon, lat);
  const Array<double> x = doubles(b[0], "lon"), y = doubles(b[1], "lat");
  Array<grid::Code> out(shape_of(x));
  const double* px = x.data();
  const double* py_ = y.data();
  grid::Code* o = out.mutable_data();
  each(x.size(), [&](py::ssize_t k) { o[k] = grid::lonlat_to_code(px[k], py_[k], level); });
  return finish(out);
}

py::object code_to_lonlat(const py::object& codes, int level) {
  const Array<grid::Code> c = codes_of(codes, level);
  Array<double> lon(shape_of(c)), lat(shape_of(c));
  const grid::Code* pc = c.data();
  double* plon = lon.mutable_data();
  double* plat = lat.mutable_data();
  each(c.size(), [&](py::ssize_t k) {
    const grid::LonLat p = grid::cell_centre(pc[k], level);
    plon[k] = p.lon;
    plat[k] = p.lat;
  });
  return py::make_tuple(finish(lon), finish(lat));
}

py::object code_to_cell(const py::object& codes, int level) {
  const Array<grid::Code> c = codes_of(codes, level);
  Array<std::int64_t> octant(shape_of(c)), row(shape_of(c)), col(shape_of(c));
  const grid::Code* pc = c.data();
  std::int64_t* po = octant.mutable_data();
  std::int64_t* pr = row.mutable_data();
  std::int64_t* pj = col.mutable_data();
  each(c.size(), [&](py::ssize_t k) {
    const grid::Cell cell = grid::cell_of(pc[k], level);
    po[k] = cell.octant;
    pr[k] = cell.row;
    pj[k] = cell.col;
  });
  return py::make_tuple(finish(octant), finish(row), finish(col));
}

py::object cell_to_code(const py::object& octant, const py::object& row, const py::object& col, int level) {
  grid::require_level(level);
  const std::vector<py::array> b = broadcast(integers(octant, "octant"), integers(row, "row"), integers(col, "col"));
  const Array<std::int64_t> o = Array<std::int64_t>::ensure(b[0]), r = Array<std::int64_t>::ensure(b[1]),
                            j = Array<std::int64_t>::ensure(b[2]);
  Array<grid::Code> out(shape_of(o));
  const std::int64_t *po = o.data(), *pr = r.data(), *pj = j.data();
  grid::Code* pc = out.mutable_data();
  const std::int64_t rows = static_cast<std::int64_t>(grid::rows_per_octant(level));
  py::ssize_t bad = -1;
  each(o.size(), [&](py::ssize_t k) {
    const bool valid = po[k] >= 0 && po[k] < grid::kOctants && pr[k] >= 0 && pr[k] < rows && pj[k] >= 0 && pj[k] <= 2 * pr[k];
    if (!valid) {
      if (bad < 0) bad = k;
      pc[k] = grid::kInvalidCode;
      return;
    }
    pc[k] = grid::code_of({static_cast<int>(po[k]), static_cast<std::uint32_t>(pr[k]), static_cast<std::uint32_t>(pj[k])}, level);
  });
  if (bad >= 0) {
    throw std::invalid_argument("cell (octant, row, col) = (" + std::to_string(po[bad]) + ", " + std::to_string(pr[bad]) + ", " +
                                std::to_string(pj[bad]) + ") is not a cell of level " + std::to_string(level) +
                                ": octants 0 to 7, rows 0 to " + std::to_string(rows - 1) + ", columns 0 to 2 row");
  }
  return finish(out);
}

// A function of each code giving `width` codes (neighbours: 3, children: 4), shape + (width,).
template <int width, class Function>
py::object codes_to_codes(const Array<grid::Code>& c, Function function) {
  Array<grid::Code> out(with_tail(shape_of(c), {width}));
  const grid::Code* pc = c.data();
  grid::Code* po = out.mutable_data();
  each(c.size(), [&](py::ssize_t k) { function(pc[k], po + width * k); });
  return std::move(out);
}

py::object neighbours(const py::object& codes, int level) {
  return codes_to_codes<3>(codes_of(codes, level), [level](grid::Code code, grid::Code* out) { grid::neighbours(code, level, out); });
}

py::object children(const py::object& codes, int level) {
  if (level == grid::kMaxLevel) {
    throw std::invalid_argument("level 24 is the finest, its cells have no children: children takes levels 0 to 23");
  }
  return codes_to_codes<4>(codes_of(codes, level), [level](grid::Code code, grid::Code* out) { grid::children(code, level, out); });
}

py::object parent(const py::object& codes, int level, const py::object& parent_level_arg) {
  grid::require_level(level);
  const int to = parent_level_arg.is_none() ? level - 1 : parent_level_arg.cast<int>();
  if (level == grid::kMinLevel) throw std::invalid_argument("level 0 cells have no parent: parent takes levels 1 to 24");
  if (to < 0 || to > level) {
    throw std::invalid_argument("parent_level " + std::to_string(to) + " is not a level from 0 to " + std::to_string(level));
  }
  const Array<grid::Code> c = codes_of(codes, level);
  Array<grid::Code> out(shape_of(c));
  const grid::Code* pc = c.data();
  grid::Code* po = out.mutable_data();
  each(c.size(), [&](py::ssize_t k) { po[k] = grid::code_of(grid::ancestor(grid::cell_of(pc[k], level), level, to), to); });
  return finish(out);
}

// A function of each cell giving `corners` lon/lat pairs, shape + (corners, 2).
template <int corners, class Function>
py::object codes_to_points(const Array<grid::Code>& c, int level, Function function) {
  Array<double> out(with_tail(shape_of(c), {corners, 2}));
  const grid::Code* pc = c.data();
  double* po = out.mutable_data();
  each(c.size(), [&](py::ssize_t k) {
    grid::LonLat p[corners];
    function(grid::cell_of(pc[k], level), p);
    for (int v = 0; v < corners; ++v) {
      po[(corners * k + v) * 2] = p[v].lon;
      po[(corners * k + v) * 2 + 1] = p[v].lat;
    }
  });
  return std::move(out);
}

py::object code_to_boundary(const py::object& codes, int level) {
  return codes_to_points<3>(codes_of(codes, level), level,
                            [level](const grid::Cell& cell, grid::LonLat* out) { grid::cell_vertices(cell, level, out); });
}

py::object code_to_polygon(const py::object& codes, int level) {
  constexpr int kCorners = grid::kMaxPolygonCorners;
  return codes_to_points<kCorners>(codes_of(codes, level), level, [level](const grid::Cell& cell, grid::LonLat* out) {
    if (grid::cell_polygon(cell, level, out) < kCorners) out[kCorners - 1] = {std::nan(""), std::nan("")};
  });
}

py::object is_valid_code(const py::object& codes, int level) {
  const py::array a = integers(codes, "codes");
  Array<bool> out(shape_of(a));
  bool* po = out.mutable_data();
  const grid::Code count = grid::is_valid_level(level) ? grid::cell_count(level) : 0;
  if (a.dtype().kind() == 'u') {
    const auto* v = static_cast<const grid::Code*>(a.data());
    each(a.size(), [&](py::ssize_t k) { po[k] = v[k] < count; });
  } else {
    const auto* v = static_cast<const std::int64_t*>(a.data());
    each(a.size(), [&](py::ssize_t k) { po[k] = v[k] >= 0 && static_cast<grid::Code>(v[k]) < count; });
  }
  return finish(out);
}

}  // namespace

void bind_grid(py::module_& m) {
  m.attr("INVALID_CODE") = py::int_(grid::kInvalidCode);
  m.attr("MIN_LEVEL") = grid::kMinLevel;
  m.attr("MAX_LEVEL") = grid::kMaxLevel;
  m.def("cell_count", [](int level) { return (grid::require_level(level), grid::cell_count(level)); }, py::arg("level"),
        "The number of cells of a level: 8 * 4**level (level 0..24).");
  m.def("lonlat_to_code", &lonlat_to_code, py::arg("lon"), py::arg("lat"), py::arg("level"),
        R"(The codes of the cells that hold the positions (lon, lat) at a level.

lon, lat: longitude and latitude (degrees); arrays or scalars, broadcast against each other.
  Any finite longitude is taken (brought into [-180, 180)); latitude lies in [-90, 90].
level: the QTM level, 0..24.
Returns uint64 codes of the inputs' shape (a Python int for scalars); INVALID_CODE where a
coordinate is NaN or infinite, or a latitude lies beyond +-90.)");
  m.def("code_to_lonlat", &code_to_lonlat, py::arg("codes"), py::arg("level"),
        R"(The centres of cells: (lon, lat) float64 arrays of the codes' shape (degrees).

A centre is the centroid of the cell's planar triangle mapped back to the sphere (docs/QTM-SPEC.md).
codes: integer codes of the level (0 .. 8 * 4**level - 1); a code out of range raises ValueError.)");
  m.def("code_to_cell", &code_to_cell, py::arg("codes"), py::arg("level"),
        R"(The cells of codes as (octant, row, col) int64 arrays of the codes' shape.

octant 0..7 (0-3 north, 0 at longitudes [0, 90), eastwards; 4-7 south), row 0 .. 2**level - 1
from the pole, col 0 .. 2 row (even: an up cell, odd: a down cell).)");
  m.def("cell_to_code", &cell_to_code, py::arg("octant"), py::arg("row"), py::arg("col"), py::arg("level"),
        "The codes of cells given as (octant, row, col) (code_to_cell's inverse); arrays broadcast.");
  m.def("neighbours", &neighbours, py::arg("codes"), py::arg("level"),
        R"(The three edge neighbours of each cell: uint64 codes, shape codes.shape + (3,).

In order: left (towards lower column), right (towards higher column), vertical (below an up
cell, across the equator in an octant's last row; above a down cell).)");
  m.def("children", &children, py::arg("codes"), py::arg("level"),
        "The four children (codes of level + 1) of each cell: shape codes.shape + (4,); level 0..23.");
  m.def("parent", &parent, py::arg("codes"), py::arg("level"), py::arg("parent_level") = py::none(),
        R"(The ancestor of each cell at parent_level (default level - 1): uint64 codes of the codes' shape.

The parent is the cell of the coarser level that holds the child's centre; parent_level
level - k is the parent taken k times.)");
  m.def("code_to_boundary", &code_to_boundary, py::arg("codes"), py::arg("level"),
        R"(The three vertices of each cell (degrees): float64, shape codes.shape + (3, 2), [..., 0] lon, [..., 1] lat.

The spec's order: up cell (i, a), (i+1, a), (i+1, a+1); down cell (i, a), (i, a+1), (i+1, a+1),
as grid vertices (row, k) of the octant; a pole vertex has the longitude of the octant's
lon' = 0 side.)");
  m.def("code_to_polygon", &code_to_polygon, py::arg("codes"), py::arg("level"),
        R"(Each cell as the ring the tool draws (degrees): float64, shape codes.shape + (4, 2), counter-clockwise, not closed.

Three corners, the fourth NaN; an octant's pole cell (row 0) has four, two on latitude +-90.
Edges are straight in lon/lat. cell_polygons() makes shapely polygons of them.)");
  m.def("is_valid_code", &is_valid_code, py::arg("codes"), py::arg("level"),
        "Whether each integer is a code of the level (0 .. 8 * 4**level - 1): a bool array of the codes' shape.");
}

}  // namespace qtmv::python
