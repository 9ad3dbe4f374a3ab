"""The grid's functions against the spec's test vectors (testdata/testvectors/) and the C++
library's results as the qtmcell tool prints them."""

import csv
import subprocess

import numpy as np
import pytest

import qtmvoronoi as q
from conftest import QTMCELL, TESTDATA

DEGREE_TOLERANCE = 1e-9  # the vectors' decimals (degrees), as tests/grid/grid_testvectors_test.cpp


def rows(name):
    with open(TESTDATA / "testvectors" / name, newline="") as f:
        return list(csv.DictReader(f))


def qtmcell(command, level, inputs):
    result = subprocess.run([QTMCELL, command, "-level", str(level)], input="\n".join(map(str, inputs)) + "\n",
                            capture_output=True, text=True, check=True)
    return result.stdout.splitlines()


def degrees_text(value):
    """A coordinate as qtmcell prints it (15 significant digits, never -0)."""
    return "%.15g" % (value + 0.0)


def test_points_to_codes_match_the_vectors():
    points = rows("points.csv")
    assert len(points) > 1000
    for level in sorted({int(r["level"]) for r in points}):
        at = [r for r in points if int(r["level"]) == level]
        lon = np.array([float(r["lon"]) for r in at])
        lat = np.array([float(r["lat"]) for r in at])
        expected = np.array([int(r["code"]) for r in at], dtype=np.uint64)
        np.testing.assert_array_equal(q.lonlat_to_code(lon, lat, level), expected)


def test_cells_match_the_vectors():
    cells = rows("cells.csv")
    assert len(cells) > 1000
    for level in sorted({int(r["level"]) for r in cells}):
        at = [r for r in cells if int(r["level"]) == level]
        codes = np.array([int(r["code"]) for r in at], dtype=np.uint64)
        column = lambda name, kind=float: np.array([kind(r[name]) for r in at])  # noqa: E731
        octant, row, col = q.code_to_cell(codes, level)
        np.testing.assert_array_equal(octant, column("octant", int))
        np.testing.assert_array_equal(row, column("row", int))
        np.testing.assert_array_equal(col, column("col", int))
        np.testing.assert_array_equal(q.cell_to_code(octant, row, col, level), codes)
        lon, lat = q.code_to_lonlat(codes, level)
        np.testing.assert_allclose(lon, column("centre_lon"), rtol=0, atol=DEGREE_TOLERANCE)
        np.testing.assert_allclose(lat, column("centre_lat"), rtol=0, atol=DEGREE_TOLERANCE)
        neighbours = q.neighbours(codes, level)
        for k, name in enumerate(["nb_left", "nb_right", "nb_vertical"]):
            np.testing.assert_array_equal(neighbours[:, k], column(name, int))
        boundary = q.code_to_boundary(codes, level)
        for k in range(3):
            np.testing.assert_allclose(boundary[:, k, 0], column(f"v{k}_lon"), rtol=0, atol=DEGREE_TOLERANCE)
            np.testing.assert_allclose(boundary[:, k, 1], column(f"v{k}_lat"), rtol=0, atol=DEGREE_TOLERANCE)


@pytest.mark.parametrize("level", [0, 1, 5, 13, 24])
def test_codes_match_qtmcell(level):
    rng = np.random.default_rng(level)
    codes = rng.integers(0, q.cell_count(level), size=300, dtype=np.uint64)
    codes[:3] = [0, q.cell_count(level) - 1, q.cell_count(level) // 2]
    lon, lat = q.code_to_lonlat(codes, level)
    octant, row, col = q.code_to_cell(codes, level)
    decoded = [f"{c} {o} {r} {j} {degrees_text(x)} {degrees_text(y)}" for c, o, r, j, x, y in zip(codes, octant, row, col, lon, lat)]
    assert decoded == qtmcell("decode", level, codes)
    assert [" ".join(map(str, n)) for n in q.neighbours(codes, level)] == qtmcell("neighbours", level, codes)
    if level > 0:
        assert list(map(str, q.parent(codes, level))) == qtmcell("parent", level, codes)
    if level < q.MAX_LEVEL:
        assert [" ".join(map(str, c)) for c in q.children(codes, level)] == qtmcell("children", level, codes)
    polygons = []
    for ring in q.code_to_polygon(codes, level):
        corners = ring[:3] if np.isnan(ring[3, 0]) else ring
        closed = list(corners) + [corners[0]]
        polygons.append("POLYGON ((" + ",".join(f"{degrees_text(x)} {degrees_text(y)}" for x, y in closed) + "))")
    assert polygons == qtmcell("polygon", level, codes)


@pytest.mark.parametrize("level", [0, 7, 16, 24])
def test_positions_match_qtmcell(level):
    rng = np.random.default_rng(100 + level)
    lon = rng.uniform(-540, 540, 500)
    lat = np.degrees(np.arcsin(rng.uniform(-1, 1, 500)))
    lon[:6], lat[:6] = [0, 180, -180, 90, 45, 0], [90, -90, 0, 0, 0, 0]
    codes = q.lonlat_to_code(lon, lat, level)
    assert list(map(str, codes)) == qtmcell("encode", level, [f"{x!r} {y!r}" for x, y in zip(lon, lat)])


def test_parent_levels_up_is_the_parent_taken_again():
    codes = np.arange(0, q.cell_count(6), 7, dtype=np.uint64)
    twice = q.parent(q.parent(codes, 6), 5)
    np.testing.assert_array_equal(q.parent(codes, 6, parent_level=4), twice)
    np.testing.assert_array_equal(q.parent(codes, 6, parent_level=6), codes)
    children = q.children(codes, 6)
    np.testing.assert_array_equal(q.parent(children, 7), np.repeat(codes[:, None], 4, axis=1))


def test_shapes_scalars_and_broadcasting():
    assert q.lonlat_to_code(0.0, 90.0, 0) == 0
    assert isinstance(q.lonlat_to_code(10.0, 10.0, 3), int)
    grid = q.lonlat_to_code(np.linspace(-170, 170, 5)[None, :], np.linspace(-80, 80, 4)[:, None], 8)
    assert grid.shape == (4, 5) and grid.dtype == np.uint64
    assert q.neighbours(grid, 8).shape == (4, 5, 3)
    assert q.code_to_boundary(grid, 8).shape == (4, 5, 3, 2)
    lon, lat = q.code_to_lonlat(5, 2)
    assert isinstance(lon, float) and isinstance(lat, float)
    assert q.cell_polygons([0, 1], 0).geom_type.tolist() == ["Polygon", "Polygon"]


def test_bad_inputs():
    assert q.lonlat_to_code([np.nan, 0.0, 1.0], [0.0, 95.0, np.inf], 5).tolist() == [q.INVALID_CODE] * 3
    np.testing.assert_array_equal(q.is_valid_code([-1, 0, 511, 512], 3), [False, True, True, False])
    with pytest.raises(ValueError, match=r"codes\[1\]: QTM code 512 is out of range at level 3: codes run from 0 to 511"):
        q.code_to_lonlat([0, 512], 3)
    with pytest.raises(ValueError, match="not negative"):
        q.neighbours([-3], 3)
    with pytest.raises(ValueError, match="QTM level 25 is out of range"):
        q.lonlat_to_code(0, 0, 25)
    with pytest.raises(ValueError, match="level 0 cells have no parent"):
        q.parent(0, 0)
    with pytest.raises(ValueError, match="level 24 is the finest"):
        q.children(0, 24)
    with pytest.raises(ValueError, match=r"is not a cell of level 2"):
        q.cell_to_code(0, 1, 3, 2)
    with pytest.raises(TypeError, match="not integers"):
        q.code_to_lonlat([1.5], 3)
