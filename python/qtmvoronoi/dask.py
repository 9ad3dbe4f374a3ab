"""qtmvoronoi.dask: a run's tile jobs as Dask tasks, so that a Dask cluster is the engine.

A level splits into N tiles of whole octant rows (the tool's -tile K/N); each tile job labels its
tile and hands back its tile product (the outline cells and cells per site of its codes: bytes,
so no shared file system is needed), and one merge task joins them (-merge) and writes the
result as a whole run does: the result equals voronoi()'s, whatever N and wherever the tasks
ran (LocalCluster, Kubernetes, Coiled, dask-jobqueue on Slurm, ...).
"""

import os
import uuid

from . import _qtmvoronoi, conversions, run

# The options a tile job takes (how the sites are read and labelled); the merge takes all.
_TILE_JOB_OPTIONS = {"distance", "device", "algorithm", "threads", "source_layers", "where", "sql", "dialect",
                     "s_srs", "open_options", "edges", "wrap", "strict", "makevalid", "memory_limit"}


def tile_product(sites, level, tile, tiles, options):
    """Tile job `tile` (1..tiles) of the run of `sites` at `level`: its tile product's bytes.

    A Dask task (it runs where the scheduler puts it): sites as voronoi() takes them (a path must
    be readable there), options voronoi()'s keywords of _TILE_JOB_OPTIONS.
    """
    options = run.make_options(level, **options)
    options.tile = (tile, tiles)
    directory = conversions.MemoryDirectory()
    try:
        source, description = conversions.sites_source(sites, directory)
        name = f"{tile}.qtmt"
        run.execute(source, directory.file(name), options, description=description)
        return directory.read(name)
    finally:
        directory.remove()


def merge(sites, level, products, options, single):
    """The merge of the tile products `products` (bytes, one per tile job) of the run of `sites`
    at `level`, read back as voronoi() returns it. A Dask task."""
    layers = options.pop("layers", "regions")
    options = run.make_options(level, layers=layers, **options)
    directory = conversions.MemoryDirectory()
    try:
        source, description = conversions.sites_source(sites, directory)
        options.merge = [directory.write(f"{k + 1}.qtmt", product) for k, product in enumerate(products)]
        return run.run_in_memory(directory, source, options, description=description, single=single)
    finally:
        directory.remove()


def voronoi(client, sites, level, tiles, *, progress=None, **options):
    """voronoi(sites, level, **options) computed on a Dask cluster as `tiles` tile jobs and a merge.

    client: a distributed.Client. sites: a GeoDataFrame, GeoSeries or (lon, lat) arrays (sent to
    the workers once, through client.scatter), or a path or OGR dataset name that every worker
    can read. level: the QTM level (0..24). tiles: N, the number of tile jobs (each labels 1/N of
    the level's rows; N at least the workers' threads keeps them busy). options: voronoi()'s
    keywords for vector output (layers, distance, device, threads, vertices, the reading
    options, ...); a raster, a destination and progress callables of voronoi() are not taken.
    progress: None, or a callable (fraction of tile jobs done, 'tiles') called on this machine
    as they finish.

    Returns what voronoi() returns for the same arguments (a GeoDataFrame, or a dict of them
    for a list of layers), equal to it row by row. KeyboardInterrupt while waiting cancels the
    tasks; a task's error is raised here (qtmvoronoi.Error with the tool's message).
    """
    import distributed

    unknown = set(options) - _TILE_JOB_OPTIONS - {"layers", "vertices", "dataset_options", "layer_options"}
    if unknown:
        raise _qtmvoronoi.OptionError(f"qtmvoronoi.dask.voronoi: options not taken here: {', '.join(sorted(unknown))} "
                                      "(tile jobs make vector output, returned as Python data)")
    if not isinstance(tiles, int) or tiles < 1:
        raise _qtmvoronoi.OptionError(f"tiles: {tiles!r} is not a positive number of tile jobs")
    run.make_options(level, **options)  # every option checked here, before any task
    single = isinstance(options.get("layers", "regions"), str)
    reading = {k: v for k, v in options.items() if k in _TILE_JOB_OPTIONS}
    # Sent once, whole: scatter takes a list's (a (lon, lat) pair's) items one by one.
    payload = os.fspath(sites) if isinstance(sites, (str, os.PathLike)) else client.scatter([sites])[0]
    token = uuid.uuid4().hex[:8]
    jobs = [client.submit(tile_product, payload, level, k, tiles, reading, key=f"qtmvoronoi-tile-{k}-of-{tiles}-{token}")
            for k in range(1, tiles + 1)]
    merged = client.submit(merge, payload, level, jobs, dict(options), single, key=f"qtmvoronoi-merge-{token}")
    try:
        if progress is not None:
            for done, _ in enumerate(distributed.as_completed(jobs), start=1):
                progress(done / tiles, "tiles")
        return merged.result()
    except BaseException:
        client.cancel(jobs + [merged])
        raise
