#!/usr/bin/python3
"""The nearest-site lon/lat raster written by hand with scipy's cKDTree: the reference that
qtmvoronoi's lon/lat raster is timed against (issue 37, item 6; bench/RESULTS.md).

    /usr/bin/python3 bench/ckdtree_raster.py [--tr 0.025] [--bands fid,boundary,distance]
        [--x lon] [--y lat] SITES.csv OUT.tif

The sites are a CSV's points (lon/lat columns, degrees); a site's FID is its data row's number
from 1, as GDAL's CSV driver numbers features. Each pixel centre takes its nearest site: the
nearest unit vector by chord, which orders as the great-circle distance does. Bands, in the order
asked: fid (the site's FID), boundary (1 where a pixel's 4-neighbour has another FID, else 0),
distance (great-circle metres from the pixel centre to its site, on the sphere of radius
6371008.8 m). The grid is qtmvoronoi's -raster lonlat -tr: origin (-180, 90), round(360 / XRES)
x round(180 / YRES) pixels, EPSG:4326; one data type for all bands, as the tool chooses it (Int32,
or Float32 with the distance band), nodata -1, and the tool's GeoTIFF creation options (tiled,
DEFLATE level 1, band interleaved, compressed on all cores).

Written in strips of whole rows of 256-pixel blocks, each strip's pixels queried at once on all
cores (workers=-1); a strip with the boundary band also queries one row above and below it.
--k2 FILE.npy also saves, per pixel, the difference of the second and the first nearest chord
(a test oracle: where it is not near zero, any nearest-site labelling agrees on the FID).
"""
import argparse
import csv
import math
import sys
import time

import numpy as np
from osgeo import gdal, osr
from scipy.spatial import cKDTree

EARTH_RADIUS_M = 6371008.8
BANDS = ("fid", "boundary", "distance")


def unit_vectors(lon_deg, lat_deg):
    lon, lat = np.radians(lon_deg), np.radians(lat_deg)
    c = np.cos(lat)
    return np.stack([c * np.cos(lon), c * np.sin(lon), np.sin(lat)], axis=-1)


def read_sites(path, x_name, y_name):
    lon, lat = [], []
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            lon.append(float(row[x_name]))
            lat.append(float(row[y_name]))
    return np.array(lon), np.array(lat), np.arange(1, len(lon) + 1, dtype=np.int64)


def parse_bands(text):
    bands = [b.strip() for b in text.split(",")]
    for b in bands:
        if b not in BANDS:
            sys.exit(f"--bands: '{b}' is not one of {', '.join(BANDS)}")
    if len(set(bands)) != len(bands):
        sys.exit(f"--bands: '{text}' names a band twice")
    return bands


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("sites")
    p.add_argument("out")
    p.add_argument("--tr", type=float, default=0.025, help="pixel size (degrees), square")
    p.add_argument("--bands", default="fid", help="from fid,boundary,distance (default fid)")
    p.add_argument("--x", default="lon")
    p.add_argument("--y", default="lat")
    p.add_argument("--k2", help="save the second minus the first nearest chord per pixel (.npy)")
    a = p.parse_args()
    bands = parse_bands(a.bands)
    t0 = time.time()
    lon, lat, fids = read_sites(a.sites, a.x, a.y)
    tree = cKDTree(unit_vectors(lon, lat))
    width, height = max(1, int(math.floor(360.0 / a.tr + 0.5))), max(1, int(math.floor(180.0 / a.tr + 0.5)))
    lon_centres = -180.0 + (np.arange(width) + 0.5) * a.tr
    lon_centres = np.where(lon_centres >= 180.0, lon_centres - 360.0, lon_centres)  # past 180: wrapped
    with_distance = "distance" in bands
    dtype, gdal_type = (np.float32, gdal.GDT_Float32) if with_distance else (np.int32, gdal.GDT_Int32)
    co = ["TILED=YES", "COMPRESS=DEFLATE", "ZLEVEL=1", "BIGTIFF=IF_SAFER", "INTERLEAVE=BAND", "NUM_THREADS=ALL_CPUS"]
    ds = gdal.GetDriverByName("GTiff").Create(a.out, width, height, len(bands), gdal_type, co)
    ds.SetGeoTransform((-180.0, a.tr, 0.0, 90.0, 0.0, -a.tr))
    srs = osr.SpatialReference()
    srs.ImportFromEPSG(4326)
    ds.SetProjection(srs.ExportToWkt())
    for k, b in enumerate(bands):
        band = ds.GetRasterBand(k + 1)
        band.SetDescription({"fid": "site_fid", "boundary": "boundary", "distance": "distance_m"}[b])
        band.SetNoDataValue(-1)
    k2 = np.empty((height, width), np.float32) if a.k2 else None

    def query(y0, y1):
        """Nearest site (index) and chord of the pixel centres of rows [y0, y1); nodata rows
        (centres past latitude -90) get index -1."""
        lat_rows = 90.0 - (np.arange(y0, y1) + 0.5) * a.tr
        lon_grid, lat_grid = np.meshgrid(lon_centres, lat_rows)
        xyz = unit_vectors(lon_grid, lat_grid).reshape(-1, 3)
        chord, index = tree.query(xyz, k=2 if k2 is not None else 1, workers=-1)
        if k2 is not None:
            k2[y0:y1] = (chord[:, 1] - chord[:, 0]).reshape(y1 - y0, width)
            chord, index = chord[:, 0], index[:, 0]
        index = index.reshape(y1 - y0, width)
        index[lat_rows < -90.0] = -1
        return index, chord.reshape(y1 - y0, width)

    strip = 256
    for y0 in range(0, height, strip):
        y1 = min(height, y0 + strip)
        halo = "boundary" in bands
        q0, q1 = (max(0, y0 - 1), min(height, y1 + 1)) if halo else (y0, y1)
        index, chord = query(q0, q1)
        fid = np.where(index >= 0, fids[np.maximum(index, 0)], -1)
        rows = slice(y0 - q0, y0 - q0 + (y1 - y0))
        for k, b in enumerate(bands):
            if b == "fid":
                values = fid[rows]
            elif b == "distance":
                values = np.where(index[rows] >= 0, 2.0 * np.arcsin(np.minimum(chord[rows] / 2.0, 1.0)) * EARTH_RADIUS_M, -1)
            else:
                differs = np.zeros(fid.shape, bool)
                differs[:, 1:] |= fid[:, 1:] != fid[:, :-1]
                differs[:, :-1] |= fid[:, :-1] != fid[:, 1:]
                differs[:, 0] |= fid[:, 0] != fid[:, -1]  # the columns at -180 and +180 touch
                differs[:, -1] |= fid[:, -1] != fid[:, 0]
                differs[1:] |= fid[1:] != fid[:-1]
                differs[:-1] |= fid[:-1] != fid[1:]
                values = np.where(fid >= 0, differs, -1)[rows]
            ds.GetRasterBand(k + 1).WriteArray(values.astype(dtype, copy=False), 0, y0)
    ds = None
    if k2 is not None:
        np.save(a.k2, k2)
    print(f"ckdtree_raster: {width} x {height} pixels, {len(fids)} sites, bands {','.join(bands)}: "
          f"{time.time() - t0:.2f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
