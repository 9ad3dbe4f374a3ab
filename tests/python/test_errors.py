"""A bad geometry, a bad option and Ctrl-C each give a clear exception and leave nothing behind
(no in-memory file, nothing at or beside the destination); progress and messages callables."""

import os
import signal
import threading
import time
import warnings

import geopandas as gpd
import pytest
from shapely.geometry import Point, Polygon

import qtmvoronoi as q

BOWTIE = Polygon([(0, 0), (10, 10), (10, 0), (0, 10)])


@pytest.mark.parametrize("to_file", [False, True])
def test_bad_geometry_under_strict(nothing_left, to_file):
    frame = gpd.GeoDataFrame({"name": ["ok", "bowtie"]}, geometry=[Point(50, 5), BOWTIE], crs="EPSG:4326")
    destination = nothing_left / "out.gpkg" if to_file else None
    with pytest.raises(q.Error, match=r"^the GeoDataFrame, layer 'sites', FID 2: invalid polygon \(Self-intersection"):
        q.voronoi(frame, 5, strict=True, destination=destination)


def test_bad_coordinates_only(nothing_left):
    frame = gpd.GeoDataFrame({"name": ["north of the pole"]}, geometry=[Point(10, 95)], crs="EPSG:4326")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(q.Error, match="the GeoDataFrame, layer 'sites': no usable site"):
            q.voronoi(frame, 5)
    assert any("FID 1: latitude beyond +-90 at (10, 95); feature skipped" in str(w.message) for w in caught)
    # The warning points at the caller's line, not into the package.
    assert all(w.filename == __file__ for w in caught if issubclass(w.category, q.QtmvoronoiWarning))


@pytest.mark.parametrize("options, error, message", [
    (dict(level=30), q.Error, "-level: QTM level 30 is out of range"),
    (dict(level=5, device="gpu"), q.OptionError, "-device: 'gpu' is not one of auto, cpu, cuda"),
    (dict(level=5, distance="far"), q.OptionError, "-distance: 'far' is not one of exact, cell"),
    (dict(level=5, algorithm="fast"), q.OptionError, "-algorithm: 'fast' is not one of auto, hier, brute"),
    (dict(level=5, layers="nope"), q.Error, "-layers: no layer 'nope'"),
    (dict(level=5, tr=1, ts=(10, 10)), q.OptionError, "-tr and -ts exclude each other"),
    (dict(level=5, raster="qtm", tr=1), q.OptionError, "-tr and -ts are for -raster lonlat"),
    (dict(level=5, open_options=["X"]), q.OptionError, "-oo: 'X' is not NAME=VALUE"),
    (dict(level=5, bands="fid"), q.OptionError, "-bands is for raster output, -layers for vector output"),
    (dict(level=5, raster="qtm", bands=["fid", "fid"]), q.OptionError, "-bands: "),
    (dict(level=5, raster="qtm", bands="height"), q.OptionError, "-bands: "),
])
def test_bad_option(centres, nothing_left, options, error, message):
    with pytest.raises(error, match="^" + message.replace("(", r"\(").replace(")", r"\)")):
        q.voronoi(centres, destination=nothing_left / "out.gpkg", **options)
    with pytest.raises(error):
        q.voronoi(centres, **options)
    assert issubclass(q.OptionError, ValueError)


def test_bad_sites():
    with pytest.raises(TypeError, match="sites: a path, a GeoDataFrame"):
        q.voronoi(42, 3)
    with pytest.raises(q.Error, match="nowhere.gpkg"):
        q.voronoi("/nowhere.gpkg", 3)


@pytest.mark.parametrize("to_file", [False, True])
def test_progress_raising_keyboard_interrupt_stops_cleanly(centres, nothing_left, to_file):
    stages = []

    def progress(fraction, stage):
        stages.append(stage)
        if stage == "label":
            raise KeyboardInterrupt
        return True

    with pytest.raises(KeyboardInterrupt):
        q.voronoi(centres, 9, progress=progress, destination=nothing_left / "out.gpkg" if to_file else None)
    assert stages[-1] == "label" and "write" not in stages


def test_ctrl_c_stops_the_run_cleanly(centres, nothing_left):
    # SIGINT from another thread once the labelling has begun, as Ctrl-C in a terminal or a
    # notebook's interrupt: the run is in C++ without the GIL; Python's handler only sets a flag,
    # and the progress callback's PyErr_CheckSignals raises KeyboardInterrupt from it.
    seen, labelling = [], threading.Event()

    def progress(fraction, stage):
        seen.append(fraction)
        if stage == "label":
            labelling.set()
        return True

    def interrupt():
        if labelling.wait(60):
            os.kill(os.getpid(), signal.SIGINT)

    thread = threading.Thread(target=interrupt)
    thread.start()
    start = time.perf_counter()
    try:
        with pytest.raises(KeyboardInterrupt):
            q.voronoi(centres, 13, layers=["regions", "boundary_cells"], device="cpu",
                      destination=nothing_left / "out.gpkg", progress=progress)
    finally:
        labelling.set()
        thread.join()
    assert time.perf_counter() - start < 60
    assert seen and seen[-1] < 1.0, "the run went on to its end"


def test_progress_false_raises_interrupted(centres, nothing_left):
    with pytest.raises(q.Interrupted, match="stopped by the progress callback: the result not written"):
        q.voronoi(centres, 8, progress=lambda fraction, stage: fraction < 0.5)
    with pytest.raises(q.Interrupted, match="out.gpkg' not written"):
        q.voronoi(centres, 8, progress=lambda fraction, stage: fraction < 0.5, destination=nothing_left / "out.gpkg")


def test_messages_callable(centres, nothing_left):
    seen = []
    q.voronoi(centres, 6, messages=lambda severity, text: seen.append((severity, text)))
    assert ("warning", "2 site(s) got no cell of their own at level 6 (FIDs 164, 241); they keep their row, with an empty geometry") in seen
    assert seen[-1][0] == "info" and seen[-1][1].startswith("241 sites read, 0 skipped; level 6")

    def failing(severity, text):
        raise RuntimeError("the sink failed")

    with pytest.raises(RuntimeError, match="the sink failed"):
        q.voronoi(centres, 6, messages=failing)


def test_gil_is_released_while_it_works(centres):
    # Another Python thread keeps counting while a run works.
    count, done = [0], threading.Event()

    def counter():
        while not done.is_set():
            count[0] += 1

    thread = threading.Thread(target=counter)
    thread.start()
    try:
        q.voronoi(centres, 10, threads=1)
    finally:
        done.set()
        thread.join()
    assert count[0] > 1000
