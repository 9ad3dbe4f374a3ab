// The per-cell grid checks, one body for the CPU tests and the CUDA kernel (as stdgpu does).
#pragma once

#include "grid/qtm.hpp"

namespace qtmv::grid::test {

/// Bits of check_cell's result, one per property that failed.
enum CellCheckFailure : unsigned {
  kFailRoundTrip = 1u << 0,        ///< code -> cell -> code is not the identity
  kFailCentreLocation = 1u << 1,   ///< the centre does not locate back in the cell
  kFailNeighbourValid = 1u << 2,   ///< a neighbour is not a cell, is the cell, or repeats
  kFailNeighbourSymmetry = 1u << 3,///< the cell is not among its neighbour's neighbours
  kFailNeighbourEdge = 1u << 4,    ///< a neighbour does not share exactly two vertices
  kFailChildLocation = 1u << 5,    ///< a child's centre does not locate in the cell
  kFailChildParent = 1u << 6,      ///< a child's parent is not the cell
  kFailParentChildren = 1u << 7,   ///< the cell is not among its parent's children
};

/// Unit vectors of a cell's three vertices.
QTMV_HD inline void vertex_vectors(const Cell& c, int level, Vec3 out[3]) {
  LonLat v[3];
  cell_vertices(c, level, v);
  for (int k = 0; k < 3; ++k) out[k] = unit_vector(v[k].lon, v[k].lat);
}

/// Checks every grid invariant that involves one cell and its relatives; returns the failed
/// properties as CellCheckFailure bits (0 when all hold).
QTMV_HD inline unsigned check_cell(Code code, int level) {
  unsigned failed = 0;
  const Cell cell = cell_of(code, level);
  if (!is_valid_cell(cell, level) || code_of(cell, level) != code) failed |= kFailRoundTrip;

  const LonLat centre = cell_centre(cell, level);
  if (lonlat_to_code(centre.lon, centre.lat, level) != code) failed |= kFailCentreLocation;

  Code nb[3];
  neighbours(code, level, nb);
  Vec3 own_vertices[3];
  vertex_vectors(cell, level, own_vertices);
  for (int k = 0; k < 3; ++k) {
    if (!is_valid_code(nb[k], level) || nb[k] == code || nb[k] == nb[(k + 1) % 3]) failed |= kFailNeighbourValid;
    Code back[3];
    neighbours(nb[k], level, back);
    if (back[0] != code && back[1] != code && back[2] != code) failed |= kFailNeighbourSymmetry;
    Vec3 their_vertices[3];
    vertex_vectors(cell_of(nb[k], level), level, their_vertices);
    int shared = 0;
    for (int p = 0; p < 3; ++p)
      for (int q = 0; q < 3; ++q) shared += chord2(own_vertices[p], their_vertices[q]) < 1e-24 ? 1 : 0;
    if (shared != 2) failed |= kFailNeighbourEdge;
  }

  if (level < kMaxLevel) {
    Code kids[4];
    children(code, level, kids);
    for (int k = 0; k < 4; ++k) {
      const LonLat kid_centre = cell_centre(kids[k], level + 1);
      if (lonlat_to_code(kid_centre.lon, kid_centre.lat, level) != code) failed |= kFailChildLocation;
      if (parent(kids[k], level + 1) != code) failed |= kFailChildParent;
    }
  }
  if (level > kMinLevel) {
    Code siblings[4];
    children(parent(code, level), level - 1, siblings);
    if (siblings[0] != code && siblings[1] != code && siblings[2] != code && siblings[3] != code)
      failed |= kFailParentChildren;
  }
  return failed;
}

/// What the CPU and the GPU must compute identically for one cell.
struct CellRecord {
  Code round_trip;
  Code centre_located;
  LonLat centre;
  Vec3 centre_vector;
  Code neighbour[3];
};

QTMV_HD inline CellRecord make_cell_record(Code code, int level) {
  CellRecord r{};
  const Cell cell = cell_of(code, level);
  r.round_trip = code_of(cell, level);
  r.centre = cell_centre(cell, level);
  r.centre_located = lonlat_to_code(r.centre.lon, r.centre.lat, level);
  r.centre_vector = cell_centre_vector(code, level);
  neighbours(code, level, r.neighbour);
  return r;
}

}  // namespace qtmv::grid::test
