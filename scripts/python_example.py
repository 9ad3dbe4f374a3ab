#!/usr/bin/python3
"""The README's Python example, run as it is written there, drawing its picture
(docs/python_regions.png): the level 9 Voronoi regions of the world's country centres, plotted
with GeoPandas' .plot().

    PYTHONPATH=build/python scripts/python_example.py [PICTURE]

Needs the built package (build/python, or an installed one) and matplotlib (Debian:
python3-matplotlib; scripts/test.sh installs it).
"""

import os
import sys

import matplotlib

matplotlib.use("Agg")  # no display: the figure goes to a file

here = os.path.dirname(os.path.abspath(__file__))
os.chdir(os.path.join(here, ".."))  # the README's paths are the checkout's
picture = sys.argv[1] if len(sys.argv) > 1 else "docs/python_regions.png"

# --- as in the README ---------------------------------------------------------------------------
import geopandas as gpd
import pandas as pd
import qtmvoronoi

centres = pd.read_csv("testdata/country_centres.csv")
sites = gpd.GeoDataFrame(centres, geometry=gpd.points_from_xy(centres.lon, centres.lat), crs="EPSG:4326")
regions = qtmvoronoi.voronoi(sites, 9)  # a GeoDataFrame: name, lon, lat, site_fid, cells, area_m2
ax = regions.plot(column="name", cmap="tab20", edgecolor="white", linewidth=0.3, figsize=(12, 6))
sites.plot(ax=ax, color="black", markersize=2)
print(regions.nlargest(3, "area_m2")[["name", "cells", "area_m2"]])
# ------------------------------------------------------------------------------------------------

ax.set_axis_off()
ax.set_title("Level 9 Voronoi regions of the world's country centres (qtmvoronoi.voronoi, GeoDataFrame.plot)")
ax.figure.savefig(picture, dpi=80, bbox_inches="tight")
print(f"wrote {picture}")
