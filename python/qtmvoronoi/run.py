"""qtmvoronoi.voronoi(): one run of the library from Python data to Python data."""

import logging
import os
import sys
import warnings

from . import _qtmvoronoi, conversions
from ._qtmvoronoi import OptionError, VoronoiOptions

_log = logging.getLogger("qtmvoronoi")

# The in-memory outputs: the drivers the tool picks for .gpkg and .tif; a raster uncompressed
# there unless the caller says otherwise (it is read once, at once).
_MEMORY_VECTOR = ("GPKG", "result.gpkg")
_MEMORY_RASTER = ("GTiff", "result.tif")


class QtmvoronoiWarning(UserWarning):
    """A warning of the run (a skipped feature, a site without a cell, ...): the tool's text."""


def _pair(value, name):
    """tr or ts as a pair: None, a number (both), or two numbers."""
    if value is None:
        return None
    if isinstance(value, (int, float)):
        return (value, value)
    value = tuple(value)
    if len(value) != 2:
        raise OptionError(f"{name}: two values, not {len(value)}")
    return value


def make_options(level=None, *, layers="regions", raster=None, tr=None, ts=None, distance="exact", device="auto",
                 algorithm="auto", threads=0, vertices="auto", source_layers=None, where=None, sql=None, dialect=None,
                 s_srs=None, open_options=(), edges="lonlat", wrap="auto", strict=False, makevalid=False,
                 data_type=None, creation_options=(), bands=None, dataset_options=(), layer_options=(),
                 memory_limit=0, format=None, overwrite=False):
    """VoronoiOptions of voronoi()'s keywords (see there), with the tool's checks of options given together."""
    if tr is not None and ts is not None:
        raise OptionError("-tr and -ts exclude each other")
    if sql and where:
        raise OptionError("-sql and -where exclude each other: put the condition in the -sql statement")
    if sql and source_layers:
        raise OptionError("-sql and -l exclude each other: the -sql statement names its tables")
    if tr is not None or ts is not None:
        # A pixel size only makes sense for the lon/lat grid, so it implies it.
        if raster == "qtm":
            raise OptionError("-tr and -ts are for -raster lonlat: the QTM-coded raster's size follows the level")
        raster = "lonlat"
    if bands is not None and raster is None:
        raise OptionError("-bands is for raster output, -layers for vector output")
    o = VoronoiOptions()
    o.level = level
    o.distance, o.device, o.algorithm, o.threads = distance, device, algorithm, threads
    o.edges, o.wrap, o.strict, o.makevalid = edges, wrap, strict, makevalid
    o.source_layers = [source_layers] if isinstance(source_layers, str) else list(source_layers or [])
    o.where, o.sql, o.dialect, o.s_srs = where or "", sql or "", dialect or "", s_srs or ""
    o.open_options = list(open_options)
    o.memory_limit = memory_limit
    o.format, o.overwrite = format or "", overwrite
    if raster is not None:
        o.output, o.raster = "raster", raster
        o.tr, o.ts = _pair(tr, "tr"), _pair(ts, "ts")
        o.data_type, o.creation_options = data_type or "", list(creation_options)
        o.bands = [bands] if isinstance(bands, str) else list(bands or [])
    else:
        o.output = "vector"
        o.layers = [layers] if isinstance(layers, str) else list(layers)
        o.vertices = vertices
        o.dataset_options, o.layer_options = list(dataset_options), list(layer_options)
    return o


def _text_progress():
    """GDAL's text progress (0...10...20...100 - done.) on stderr."""
    state = {"ticks": -1}

    def show(fraction, stage):
        """Prints the dots up to `fraction` (0..1)."""
        tick = max(0, min(40, int(fraction * 40)))
        while tick > state["ticks"]:
            state["ticks"] += 1
            t = state["ticks"]
            sys.stderr.write(f"{t // 4 * 10}" if t % 4 == 0 else ".")
            if t == 40:
                sys.stderr.write(" - done.\n")
        sys.stderr.flush()
        return True

    return show, lambda: None


def _tqdm_progress():
    """A tqdm bar (tqdm.auto: a widget in notebooks) over the run's fraction, its stage as the description."""
    from tqdm.auto import tqdm

    bar = tqdm(total=1000, unit="‰", desc="qtmvoronoi", leave=False)

    def show(fraction, stage):
        """Moves the bar to `fraction` (0..1), `stage` its description."""
        done = int(round(fraction * 1000))
        if done > bar.n:
            bar.update(done - bar.n)
        if stage and bar.desc != stage:
            bar.set_description(stage, refresh=False)
        return True

    return show, bar.close


def progress_callback(progress):
    """(callable, close) for voronoi()'s progress: None/False, True (tqdm, else GDAL's text progress), or a callable."""
    if progress is None or progress is False:
        return None, lambda: None
    if progress is True:
        try:
            return _tqdm_progress()
        except ImportError:
            return _text_progress()
    if not callable(progress):
        raise TypeError("progress: None, True or a callable (fraction, stage)")
    return progress, lambda: None


def _caller_level():
    """warnings.warn's stacklevel that names the first frame outside this package (the user's call)."""
    here = os.path.dirname(os.path.abspath(__file__))
    frame, level = sys._getframe(1), 1
    while frame is not None and os.path.dirname(os.path.abspath(frame.f_code.co_filename)) == here:
        frame, level = frame.f_back, level + 1
    return level


def message_sink(messages, rename):
    """The run's message callable: the caller's, or warnings (QtmvoronoiWarning), info lines to the
    logger 'qtmvoronoi', QTMV_TRACE's lines to stderr; `rename(text)` first."""
    if messages is not None:
        return lambda severity, text: messages(severity, rename(text))

    def default(severity, text):
        """One message of the run to warnings, the logger or stderr."""
        text = rename(text)
        if severity == "warning":
            warnings.warn(text, QtmvoronoiWarning, stacklevel=_caller_level())
        elif severity == "debug":
            sys.stderr.write(f"qtmvoronoi: {text}\n")
        else:
            _log.info(text)

    return default


def execute(source, destination, options, progress=None, messages=None, description=None):
    """run_voronoi with voronoi()'s progress and messages. description: what an in-memory source
    is (a GeoDataFrame, ...), named in messages and errors instead of its /vsimem/ name, as an
    in-memory destination is named 'the result'."""
    names = {}
    if description:
        names[f"'{source}'"] = description
    if destination.startswith("/vsimem/qtmvoronoi-"):
        names[f"'{destination}'"] = "the result"

    def rename(text):
        """`text` with the in-memory names replaced by what they are."""
        for name, said in names.items():
            text = text.replace(name, said)
        return text

    callback, close = progress_callback(progress)
    try:
        return _qtmvoronoi.run_voronoi(source, destination, options, callback, message_sink(messages, rename))
    except _qtmvoronoi.Error as e:
        if rename(str(e)) != str(e):
            raise type(e)(rename(str(e))) from None
        raise
    finally:
        close()


def read_result(directory, name, options, summary):
    """The run's in-memory output as Python data: a GeoDataFrame, a dict of them, or a DataArray."""
    path = directory.file(name)
    attrs = summary.to_dict()
    if summary.raster:
        result = conversions.read_raster(path)
        result.attrs["summary"] = attrs
        return result
    frames = {layer: conversions.read_layer(path, layer) for layer in options.layers}
    for frame in frames.values():
        frame.attrs["summary"] = attrs
    return frames


def voronoi(sites, level=None, *, layers="regions", raster=None, tr=None, ts=None, distance="exact", device="auto",
            algorithm="auto", threads=0, vertices="auto", source_layers=None, where=None, sql=None, dialect=None,
            s_srs=None, open_options=(), edges="lonlat", wrap="auto", strict=False, makevalid=False, data_type=None,
            creation_options=(), bands=None, dataset_options=(), layer_options=(), memory_limit=0,
            destination=None, format=None, overwrite=False, progress=None, messages=None):
    """The spherical Voronoi diagram of `sites` on the QTM grid at `level`, as Python data.

    The library's run (the tool qtmvoronoi's, man qtmvoronoi): each cell of the level is labelled
    with its nearest site (great-circle distance to the site's exact geometry), and the regions,
    their edges and boundary cells are traced, or a raster of the labels is made.

    sites: a GeoDataFrame or GeoSeries (points, lines, polygons; any CRS, taken from the frame);
        a path or any OGR dataset name (str, os.PathLike); or a pair (lon, lat) of arrays of
        points (degrees, EPSG:4326). A frame's rows are the sites in order: row k has FID k + 1
        (the regions' site_fid), its columns the regions' attributes.
    level: QTM level 0..24 (cells of about 10 000 km / 2**level); None: 9, or for a lon/lat raster
        sized by tr or ts the level about four times finer than a pixel.
    layers: the vector layers, of 'regions' (one MultiPolygon per site, the sites' columns,
        site_fid, cells, area_m2 in square metres), 'boundary_cells', 'voronoi_edges' (site_a,
        site_b, length_m in metres) and 'cells' (one row per cell: only for coarse levels). A name
        gives a GeoDataFrame, a list of names a dict of them by name.
    raster: 'qtm' (one pixel per cell) or 'lonlat' (EPSG:4326 over the globe): an
        xarray.DataArray (band, y, x) of bands site_fid, boundary, distance_m (metres) instead of
        layers. tr: its pixel size (degrees; a number or (x, y)); ts: its size (width, height)
        (pixels); either implies raster='lonlat'. data_type: -ot (Byte .. Float64);
        creation_options: -co NAME=VALUE. bands: -bands, the bands in order, of 'fid',
        'boundary', 'distance' (a name or a list; None: all three): an allocation raster is
        often bands='fid' alone.
    distance: 'exact' (to the sites' geometry) or 'cell' (between cell centres, the seed paper's).
    device: 'auto', 'cpu', 'cuda', 'cuda:N', 'cuda:N,M,...', 'cuda:all': the same results on each.
    algorithm: 'auto', 'hier' or 'brute'. threads: CPU threads (0: all; the same results).
    vertices: 'auto' or 'all' (every cell vertex along parallels, as geodesic readers need) or
        'corners' (planar readers only).
    source_layers, where, sql, dialect, s_srs, open_options (NAME=VALUE), edges ('lonlat' or
        'geodesic': how a segment between two vertices runs), wrap ('auto' or 'none'), strict (a
        skipped feature or an invalid polygon is an error), makevalid: how the sites are read,
        as the tool's -l, -where, -sql, -dialect, -s_srs, -oo, -edges, -wrap, -strict, -makevalid.
    memory_limit: host memory the run's products may take (bytes); 0: 80% of the RAM.
    destination: None (the default): nothing is written; the result comes back as Python data.
        A file name: the dataset is written there as the tool writes it (format: -of, a GDAL
        driver's short name; default from the extension; dataset_options -dsco, layer_options
        -lco; overwrite replaces an existing one), and the VoronoiSummary is returned.
    progress: None (none), True (a tqdm bar when tqdm is installed, else GDAL's text progress on
        stderr), or a callable (fraction 0..1, stage) whose False stops the run.
    messages: None (warnings as QtmvoronoiWarning, informative lines to the logger 'qtmvoronoi',
        QTMV_TRACE's lines to stderr), or a callable (severity 'info' | 'warning' | 'debug', text).

    The GIL is released while the run works. Ctrl-C raises KeyboardInterrupt, and a progress
    callable's False qtmvoronoi.Interrupted, once the run has stopped and undone its work; a
    failed run raises qtmvoronoi.Error with the tool's message, a bad option
    qtmvoronoi.OptionError; in each case nothing is left behind (no in-memory file, no file or
    temporary file at the destination). The result's attrs['summary'] holds the run's
    VoronoiSummary as a dict (counts, seconds per stage).
    """
    if destination is None and format:
        raise OptionError("format is for a destination: without one the result comes back as Python data")
    options = make_options(level, layers=layers, raster=raster, tr=tr, ts=ts, distance=distance, device=device,
                           algorithm=algorithm, threads=threads, vertices=vertices, source_layers=source_layers,
                           where=where, sql=sql, dialect=dialect, s_srs=s_srs, open_options=open_options,
                           edges=edges, wrap=wrap, strict=strict, makevalid=makevalid, data_type=data_type,
                           creation_options=creation_options, bands=bands, dataset_options=dataset_options,
                           layer_options=layer_options, memory_limit=memory_limit, format=format,
                           overwrite=overwrite)
    directory = conversions.MemoryDirectory()
    try:
        source, description = conversions.sites_source(sites, directory)
        if destination is not None:
            return execute(source, os.fspath(destination), options, progress, messages, description)
        return run_in_memory(directory, source, options, progress, messages, description, single=isinstance(layers, str))
    finally:
        directory.remove()


def run_in_memory(directory, source, options, progress=None, messages=None, description=None, single=False):
    """Runs into `directory` (a MemoryDirectory) and reads the result back (see read_result);
    `single`: the one layer's GeoDataFrame rather than a dict."""
    raster = options.output == "raster"
    driver, name = _MEMORY_RASTER if raster else _MEMORY_VECTOR
    options.format = driver
    if raster and not any(o.upper().startswith("COMPRESS=") for o in options.creation_options):
        options.creation_options = options.creation_options + ["COMPRESS=NONE"]
    summary = execute(source, directory.file(name), options, progress, messages, description)
    result = read_result(directory, name, options, summary)
    if isinstance(result, dict) and single:
        return next(iter(result.values()))
    return result
