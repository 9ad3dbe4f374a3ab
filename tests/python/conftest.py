"""Fixtures of the Python package's tests: the built tools and the test data (CTest passes their
paths: QTMV_TOOL, QTMCELL, QTMV_TESTDATA; PYTHONPATH holds the build's python/), the country
centres as a GeoDataFrame, the tool run by hand, and the check that nothing is left behind."""

import os
import subprocess
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
TESTDATA = Path(os.environ.get("QTMV_TESTDATA", HERE.parent.parent / "testdata"))
TOOL = os.environ.get("QTMV_TOOL", str(HERE.parent.parent / "build/tools/qtmvoronoi/qtmvoronoi"))
QTMCELL = os.environ.get("QTMCELL", str(HERE.parent.parent / "build/tools/qtmcell/qtmcell"))
CENTRES_CSV = TESTDATA / "country_centres.csv"
COUNTRIES = TESTDATA / "world_atlas_countries_110m.gpkg"
# The CSV driver reads the centres' points with these open options (as the README's examples).
CENTRES_OPTIONS = ["-oo", "X_POSSIBLE_NAMES=lon", "-oo", "Y_POSSIBLE_NAMES=lat", "-s_srs", "EPSG:4326"]


def run_tool(*args):
    """Runs the tool (quiet, on the CPU); its stderr on failure."""
    result = subprocess.run([TOOL, "-q", "-device", "cpu", *map(str, args)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return result


@pytest.fixture(scope="session")
def centres():
    """The country centres (testdata/country_centres.csv: lon, lat, name) as a GeoDataFrame of
    points, the numbers parsed as GDAL's CSV reader parses them (correctly rounded)."""
    import geopandas as gpd
    import pandas as pd

    frame = pd.read_csv(CENTRES_CSV, float_precision="round_trip")
    return gpd.GeoDataFrame(frame, geometry=gpd.points_from_xy(frame.lon, frame.lat), crs="EPSG:4326")


@pytest.fixture(scope="session")
def countries():
    """Natural Earth's 110m countries (testdata: layer countries_110m) as a GeoDataFrame."""
    import geopandas as gpd

    return gpd.read_file(COUNTRIES, layer="countries_110m")


def memory_files():
    """qtmvoronoi's directories in GDAL's in-memory file system."""
    from osgeo import gdal

    return [n for n in gdal.ReadDir("/vsimem/") or [] if n.startswith("qtmvoronoi")]


@pytest.fixture
def nothing_left(tmp_path):
    """A directory for a destination; after the test, nothing of a run may be left in it (no
    temporary directory) nor in /vsimem/."""
    before = set(os.listdir(tmp_path))
    yield tmp_path
    assert memory_files() == []
    assert set(os.listdir(tmp_path)) == before
