"""Raster results as xarray.DataArray, equal to the tool's GeoTIFF: values, bands, georeferencing."""

import numpy as np
import pytest
from osgeo import gdal

import qtmvoronoi as q
from conftest import CENTRES_CSV, CENTRES_OPTIONS, COUNTRIES, run_tool


def read_tiff(path):
    ds = gdal.Open(str(path))
    bands = [ds.GetRasterBand(k + 1).GetDescription() for k in range(ds.RasterCount)]
    return ds.ReadAsArray(), bands, ds.GetGeoTransform(), ds.GetMetadata()


def test_qtm_raster_equals_the_tools_geotiff(centres, tmp_path):
    run_tool("-level", 7, "-raster", "qtm", *CENTRES_OPTIONS, CENTRES_CSV, tmp_path / "tool.tif")
    values, bands, _, metadata = read_tiff(tmp_path / "tool.tif")
    raster = q.voronoi(centres, 7, raster="qtm")
    assert raster.dims == ("band", "row", "col")
    assert raster.band.values.tolist() == bands == ["site_fid", "boundary", "distance_m"]
    assert raster.dtype == values.dtype
    np.testing.assert_array_equal(raster.values, values)
    assert raster.attrs["QTM_LEVEL"] == metadata["QTM_LEVEL"] == "7"
    assert raster.attrs["nodata"] == -1


@pytest.mark.parametrize("sizing", [["-tr", "0.5", "0.5"], ["-ts", "720", "360", "-ot", "Float64"]])
def test_lonlat_raster_equals_the_tools_geotiff(countries, tmp_path, sizing):
    run_tool("-level", 8, "-l", "countries_110m", *sizing, COUNTRIES, tmp_path / "tool.tif")
    values, bands, transform, _ = read_tiff(tmp_path / "tool.tif")
    options = dict(tr=0.5) if sizing[0] == "-tr" else dict(ts=(720, 360), data_type="Float64")
    raster = q.voronoi(countries, 8, **options)
    assert raster.dims == ("band", "y", "x") and raster.dtype == values.dtype
    np.testing.assert_array_equal(raster.values, values)
    assert raster.x.values[0] == transform[0] + transform[1] / 2
    assert raster.y.values[-1] == transform[3] + (values.shape[1] - 0.5) * transform[5]
    assert raster.spatial_ref.attrs["GeoTransform"].split() == [repr(v) for v in transform]
    assert "WGS 84" in raster.spatial_ref.attrs["crs_wkt"]


def test_raster_destination_is_the_tools_file(centres, tmp_path):
    run_tool("-level", 6, "-raster", "lonlat", "-tr", "1", "1", *CENTRES_OPTIONS, CENTRES_CSV, tmp_path / "tool.tif")
    summary = q.voronoi(centres, 6, raster="lonlat", tr=(1, 1), destination=tmp_path / "ours.tif")
    assert summary.raster
    assert (tmp_path / "ours.tif").read_bytes() == (tmp_path / "tool.tif").read_bytes()


def test_bands_chosen_are_the_tools_and_the_full_runs(centres, tmp_path):
    run_tool("-level", 7, "-raster", "qtm", "-bands", "distance,fid", *CENTRES_OPTIONS, CENTRES_CSV,
             tmp_path / "tool.tif")
    values, bands, _, _ = read_tiff(tmp_path / "tool.tif")
    chosen = q.voronoi(centres, 7, raster="qtm", bands=["distance", "fid"])
    assert chosen.band.values.tolist() == bands == ["distance_m", "site_fid"]
    np.testing.assert_array_equal(chosen.values, values)
    whole = q.voronoi(centres, 7, raster="qtm")
    np.testing.assert_array_equal(chosen.sel(band="site_fid").values, whole.sel(band="site_fid").values)
    fid = q.voronoi(centres, 7, raster="qtm", bands="fid")
    assert fid.band.values.tolist() == ["site_fid"]
    np.testing.assert_array_equal(fid.values[0], whole.sel(band="site_fid").values)


def test_raster_parts_and_their_index_are_the_whole_raster(tmp_path):
    # -tile K/N -part with a raster destination from Python: each part a band of the whole raster's
    # rows; their index (-merge -of VRT), read through GDAL, is the whole raster.
    options = dict(level=6, raster="lonlat", device="cpu", s_srs="EPSG:4326",
                   open_options=["X_POSSIBLE_NAMES=lon", "Y_POSSIBLE_NAMES=lat"])
    q.run_voronoi(str(CENTRES_CSV), str(tmp_path / "whole.tif"), q.VoronoiOptions(**options))
    (tmp_path / "parts").mkdir()
    for k in (1, 2, 3):
        part = q.VoronoiOptions(**options)
        part.tile = (k, 3)
        part.part = True
        q.run_voronoi(str(CENTRES_CSV), str(tmp_path / "parts" / f"{k}.tif"), part)
    index = q.VoronoiOptions()
    index.merge = [str(tmp_path / "parts")]
    index.format = "VRT"
    summary = q.run_voronoi("", str(tmp_path / "index.vrt"), index)
    assert summary.raster and summary.device == "index of 3 parts"
    whole, whole_bands, whole_transform, _ = read_tiff(tmp_path / "whole.tif")
    values, bands, transform, metadata = read_tiff(tmp_path / "index.vrt")
    np.testing.assert_array_equal(values, whole)
    assert bands == whole_bands and transform == whole_transform and metadata["QTM_LEVEL"] == "6"
    _, _, second, _ = read_tiff(tmp_path / "parts" / "2.tif")
    height = whole.shape[1]
    assert second[3] == whole_transform[3] + (height // 3) * whole_transform[5]
