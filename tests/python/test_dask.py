"""qtmvoronoi.dask.voronoi on a LocalCluster of 2 workers: the tile jobs as Dask tasks and their
merge equal the single run."""

import pytest
from distributed import Client, LocalCluster
from geopandas.testing import assert_geodataframe_equal

import qtmvoronoi as q
import qtmvoronoi.dask
from conftest import COUNTRIES


@pytest.fixture(scope="module")
def client():
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        with Client(cluster) as c:
            yield c


@pytest.mark.parametrize("tiles", [1, 3, 8])
def test_frame_tiles_equal_the_single_run(client, centres, tiles):
    layers = ["regions", "boundary_cells", "voronoi_edges"]
    done = []
    result = q.dask.voronoi(client, centres, 9, tiles=tiles, layers=layers, progress=lambda f, s: done.append(f))
    single = q.voronoi(centres, 9, layers=layers)
    for layer in layers:
        assert_geodataframe_equal(result[layer], single[layer], check_less_precise=False)
    assert done[-1] == 1.0 and len(done) == tiles


def test_lonlat_tiles_equal_the_single_run(client, centres):
    sites = (centres.lon.to_numpy(), centres.lat.to_numpy())
    result = q.dask.voronoi(client, sites, 8, tiles=5, layers=["regions", "voronoi_edges"])
    single = q.voronoi(sites, 8, layers=["regions", "voronoi_edges"])
    for layer in single:
        assert_geodataframe_equal(result[layer], single[layer], check_less_precise=False)


def test_path_tiles_equal_the_single_run(client):
    options = dict(source_layers="countries_110m", distance="cell")
    result = q.dask.voronoi(client, str(COUNTRIES), 7, tiles=4, **options)
    assert_geodataframe_equal(result, q.voronoi(str(COUNTRIES), 7, **options), check_less_precise=False)


def test_refusals(client, centres):
    with pytest.raises(q.OptionError, match="options not taken here: raster"):
        q.dask.voronoi(client, centres, 6, tiles=2, raster="qtm")
    with pytest.raises(q.OptionError, match="tiles: 0 is not a positive number"):
        q.dask.voronoi(client, centres, 6, tiles=0)
    with pytest.raises(q.OptionError, match="-device"):
        q.dask.voronoi(client, centres, 6, tiles=2, device="gpu")


def test_a_failing_tile_job_raises_the_tools_message(client, centres):
    with pytest.raises(q.Error, match="-level: QTM level 25 is out of range"):
        q.dask.voronoi(client, centres, 25, tiles=2)
