#!/usr/bin/env bash
# Builds everything and runs the main job on the data shipped in testdata/: the spherical Voronoi
# diagrams of the world's country centres (points) and of Natural Earth's countries (polygons)
# at level 9, as GeoPackage layers and as rasters, in build/demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
# GDAL's command-line tools make the picture (build/demo/countries_voronoi.png) from the raster.
scripts/deps.sh gdal-bin
scripts/build.sh
qtmvoronoi=build/tools/qtmvoronoi/qtmvoronoi
out=build/demo
mkdir -p "$out"
level=9
# country_centres.csv is lon,lat,name: GDAL's CSV driver reads the points with these open options.
centres=(-oo X_POSSIBLE_NAMES=lon -oo Y_POSSIBLE_NAMES=lat -s_srs EPSG:4326 testdata/country_centres.csv)
countries=(-l countries_110m testdata/world_atlas_countries_110m.gpkg)

echo "== the country centres' regions, boundary cells and Voronoi edges at level $level"
"$qtmvoronoi" -progress -overwrite -level $level "${centres[@]}" "$out/centres.gpkg"
echo "== the same as a QTM-coded raster (one pixel per cell: site FID, boundary, distance)"
"$qtmvoronoi" -progress -overwrite -level $level "${centres[@]}" "$out/centres_qtm.tif"
echo "== the regions nearest to each country (polygon sites)"
"$qtmvoronoi" -progress -overwrite -level $level "${countries[@]}" "$out/countries.gpkg"
echo "== the same as a lon/lat raster of 0.25 degree pixels"
"$qtmvoronoi" -progress -overwrite -level $level -tr 0.25 0.25 "${countries[@]}" "$out/countries_lonlat.tif"

# With GDAL's command-line tools (Debian: gdal-bin, installed above), a look at the results and
# the picture.
if command -v ogrinfo > /dev/null; then
  echo "== the five largest regions of the country centres"
  ogrinfo -q -sql "SELECT name, cells, CAST(area_m2 / 1e6 AS INTEGER) AS area_km2 FROM regions ORDER BY area_m2 DESC LIMIT 5" \
    "$out/centres.gpkg" | grep -E "^  (name|cells|area_km2) "
fi
if command -v gdaldem > /dev/null; then
  # Each country's region in a colour of its own (FID -> colour).
  awk 'BEGIN { srand(7); print "nv 0 0 0 0"; print "-1 0 0 0 0";
               for (f = 0; f <= 300; f++) printf "%d %d %d %d\n", f, 80 + int(rand() * 160), 80 + int(rand() * 160), 80 + int(rand() * 160) }' \
    > "$out/palette.txt"
  gdaldem color-relief -q -b 1 -nearest_color_entry -alpha "$out/countries_lonlat.tif" "$out/palette.txt" "$out/regions.tif"
  gdal_translate -q -of PNG "$out/regions.tif" "$out/countries_voronoi.png"
  rm -f "$out/regions.tif" "$out/palette.txt" "$out/countries_voronoi.png.aux.xml"
  echo "== picture: $out/countries_voronoi.png"
fi
ls -l "$out"
