"""voronoi() from a GeoDataFrame, lon/lat arrays and a path, equal row by row to the tool's
GeoPackage of the same sites (read with geopandas.read_file), and to a file when asked for one."""

import warnings

import geopandas as gpd
import numpy as np
import pytest
from geopandas.testing import assert_geodataframe_equal

import qtmvoronoi as q
from conftest import CENTRES_CSV, CENTRES_OPTIONS, COUNTRIES, run_tool

LAYERS = ["regions", "boundary_cells", "voronoi_edges"]


def tool_layers(path, layers):
    return {layer: gpd.read_file(path, layer=layer) for layer in layers}


def assert_same_layers(result, expected):
    assert list(result) == list(expected)
    for layer in expected:
        assert_geodataframe_equal(result[layer], expected[layer], check_less_precise=False)


@pytest.mark.parametrize("level, distance", [(9, "exact"), (8, "cell")])
def test_centres_frame_equals_the_tools_geopackage(centres, tmp_path, level, distance):
    run_tool("-level", level, "-distance", distance, *CENTRES_OPTIONS, CENTRES_CSV, tmp_path / "tool.gpkg")
    result = q.voronoi(centres, level, layers=LAYERS, distance=distance, device="cpu")
    assert_same_layers(result, tool_layers(tmp_path / "tool.gpkg", LAYERS))
    assert result["regions"].attrs["summary"]["sites"] == 241


def test_countries_frame_equals_the_tools_geopackage(countries, tmp_path):
    run_tool("-level", 8, "-l", "countries_110m", "-layers", "regions,voronoi_edges", COUNTRIES, tmp_path / "tool.gpkg")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = q.voronoi(countries, 8, layers=["regions", "voronoi_edges"])
    assert_same_layers(result, tool_layers(tmp_path / "tool.gpkg", ["regions", "voronoi_edges"]))
    # The reader's warnings name the frame, not its in-memory GeoPackage.
    texts = [str(w.message) for w in caught if issubclass(w.category, q.QtmvoronoiWarning)]
    assert any(t.startswith("the GeoDataFrame, layer 'sites', FID 15: invalid polygon") for t in texts), texts
    assert not any("/vsimem/" in t for t in texts)


def test_one_layer_is_a_frame_and_a_path_is_read_as_the_tool_reads_it(tmp_path):
    run_tool("-level", 7, "-layers", "regions", *CENTRES_OPTIONS, CENTRES_CSV, tmp_path / "tool.gpkg")
    result = q.voronoi(str(CENTRES_CSV), 7, open_options=["X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"],
                       s_srs="EPSG:4326")
    assert isinstance(result, gpd.GeoDataFrame)
    assert_geodataframe_equal(result, gpd.read_file(tmp_path / "tool.gpkg", layer="regions"), check_less_precise=False)


def test_lonlat_arrays_are_points_without_attributes(centres, tmp_path):
    run_tool("-level", 8, "-layers", "regions", *CENTRES_OPTIONS, CENTRES_CSV, tmp_path / "tool.gpkg")
    result = q.voronoi((centres.lon.to_numpy(), centres.lat.to_numpy()), 8)
    expected = gpd.read_file(tmp_path / "tool.gpkg", layer="regions").drop(columns=["lon", "lat", "name"])
    assert_geodataframe_equal(result, expected, check_less_precise=False)


def test_attribute_types_and_nulls_reach_the_regions(tmp_path):
    import pandas as pd

    frame = gpd.GeoDataFrame(
        {"i": pd.array([1, None, 3], dtype="Int64"), "f": [0.5, np.nan, 2.25], "s": ["a", None, "ü"],
         "b": [True, False, True], "t": np.array(["2020-01-02T03:04:05", "NaT", "1999-12-31T23:59:59"], dtype="datetime64[ns]")},
        geometry=gpd.points_from_xy([0, 90, -120], [10, -40, 60]), crs="EPSG:4326")
    regions = q.voronoi(frame, 4)
    assert regions.s.tolist()[::2] == ["a", "ü"] and regions.b.tolist() == [True, False, True]
    assert regions.site_fid.tolist() == [1, 2, 3]
    assert regions.cells.sum() == q.cell_count(4)
    # What a GeoPackage of them gives through geopandas.read_file (nulls NaN and NaT).
    q.voronoi(frame, 4, destination=tmp_path / "attributes.gpkg")
    assert_geodataframe_equal(regions, gpd.read_file(tmp_path / "attributes.gpkg", layer="regions"), check_less_precise=False)


def test_another_crs_is_taken_from_the_frame(centres):
    mercator = centres.to_crs("EPSG:3857")
    regions = q.voronoi(mercator, 6)
    reference = q.voronoi(centres, 6)
    # The points went through a projection and back: the same cells at this level.
    assert regions.cells.tolist() == reference.cells.tolist()


def test_destination_writes_the_tools_file(centres, tmp_path):
    run_tool("-level", 7, *CENTRES_OPTIONS, CENTRES_CSV, tmp_path / "tool.gpkg")
    summary = q.voronoi(centres, 7, layers=LAYERS, destination=tmp_path / "ours.gpkg")
    assert isinstance(summary, q.VoronoiSummary) and summary.driver == "GPKG" and summary.sites == 241
    assert_same_layers(tool_layers(tmp_path / "ours.gpkg", LAYERS), tool_layers(tmp_path / "tool.gpkg", LAYERS))
    with pytest.raises(q.Error, match="exists: use -overwrite"):
        q.voronoi(centres, 7, destination=tmp_path / "ours.gpkg")


def test_run_voronoi_is_the_tool(tmp_path):
    run_tool("-level", 6, "-layers", "regions", *CENTRES_OPTIONS, CENTRES_CSV, tmp_path / "tool.gpkg")
    options = q.VoronoiOptions(level=6, layers=["regions"], device="cpu", s_srs="EPSG:4326",
                               open_options=["X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"])
    seen = []
    summary = q.run_voronoi(str(CENTRES_CSV), str(tmp_path / "lib.gpkg"), options,
                            progress=lambda f, s: seen.append(f) is None, messages=lambda sev, text: seen.append(text))
    assert summary.level == 6 and summary.line() in seen and 1.0 in seen
    assert_geodataframe_equal(gpd.read_file(tmp_path / "lib.gpkg"), gpd.read_file(tmp_path / "tool.gpkg"))


def test_a_gpu_gives_the_cpus_result(centres):
    # On a host with a CUDA device and a CUDA build; skipped elsewhere.
    try:
        gpu = q.voronoi(centres, 10, layers=LAYERS, device="cuda")
    except q.Error as e:
        pytest.skip(f"no CUDA device here: {e}")
    assert_same_layers(gpu, q.voronoi(centres, 10, layers=LAYERS, device="cpu"))
    raster = q.voronoi(centres, 9, raster="qtm", device="cuda")
    np.testing.assert_array_equal(raster.values, q.voronoi(centres, 9, raster="qtm", device="cpu").values)


def test_parts_and_their_index_dissolve_into_the_whole_run(tmp_path):
    # -tile K/N -part from Python, then the index (-merge -of VRT): geopandas reads the index as one
    # layer whose rows, dissolved by site_fid, have the whole run's cells and areas.
    options = dict(level=6, layers=["regions"], device="cpu", s_srs="EPSG:4326",
                   open_options=["X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"])
    q.run_voronoi(str(CENTRES_CSV), str(tmp_path / "whole.gpkg"), q.VoronoiOptions(**options))
    (tmp_path / "parts").mkdir()
    for k in (1, 2, 3):
        part = q.VoronoiOptions(**options)
        part.tile = (k, 3)
        part.part = True
        q.run_voronoi(str(CENTRES_CSV), str(tmp_path / "parts" / f"{k}.gpkg"), part)
    index = q.VoronoiOptions()
    index.merge = [str(tmp_path / "parts")]
    index.format = "VRT"
    summary = q.run_voronoi("", str(tmp_path / "index.vrt"), index)
    assert summary.device == "index of 3 parts"
    whole = gpd.read_file(tmp_path / "whole.gpkg")
    try:  # fiona reads only the drivers it lists; GDAL's OGR_VRT is one to add
        import fiona
        fiona.supported_drivers.setdefault("OGR_VRT", "r")
    except ImportError:
        pass
    parts = gpd.read_file(tmp_path / "index.vrt")
    assert len(parts) > whole["cells"].gt(0).sum()
    dissolved = parts.groupby("site_fid")[["cells", "area_m2"]].sum()
    expected = whole[whole["cells"] > 0].set_index("site_fid")[["cells", "area_m2"]].sort_index()
    assert list(dissolved.index) == list(expected.index)
    assert (dissolved["cells"] == expected["cells"]).all()
    assert np.allclose(dissolved["area_m2"], expected["area_m2"], rtol=1e-9, atol=0)
