// Vector output: the Voronoi regions, boundary cells, Voronoi edges and cells of a labelled
// level, through any OGR driver, all in EPSG:4326 (longitude, latitude order).
//
// Layers (VectorOptions::layers, written in the order given):
//   regions         one MultiPolygon per site, in site order: the union of its cells, traced
//                   from the grid's topology (trace_regions), cut at +-180 and running along
//                   latitude +-90 at the poles. Fields: every field of the source, then
//                   site_fid (Integer64), cells (Integer64: cells labelled with the site),
//                   area_m2 (Real: square metres on the WGS84 ellipsoid). A site without cells
//                   gets its row with an empty geometry; with a null one where the driver
//                   refuses empties but keeps nulls (MapInfo), and none where it holds neither
//                   (FlatGeobuf, ...: the rows are named in a warning): EmptyRows in
//                   vector_dataset_writer.hpp.
//   boundary_cells  one Polygon per boundary cell: code (Integer64), site_fid (Integer64).
//   voronoi_edges   one MultiLineString per pair of neighbouring sites a < b (site ids): the cell
//                   edges between their cells, linked into lines. Fields site_a, site_b (the
//                   sites' FIDs, Integer64), length_m (Real: metres, geodesic on WGS84; the
//                   edges' lengths summed in fixed point, 2^-30 m, so in any order to the same
//                   bits; after regions, from the regions' own pass over the edges).
//   cells           every cell as a Polygon: code, site_fid, distance_m (Real, metres; null when
//                   not computed), boundary (Integer, boolean subtype).
//
// Composite sites (several source layers, SiteTable::source_count() > 1): regions take the union
// of the layers' fields by name (of a type that holds every layer's values: String where they
// differ, Integer64 for Integer and Integer64, Real for an integer and Real; with a warning
// naming the field, the layers and their types) and a site_layer field
// (String) naming each site's layer; boundary_cells and cells get site_layer too, voronoi_edges
// layer_a and layer_b. FIDs stay those of their layer.
//
// Field names: the source's fields keep their names; one of ours whose name a source field
// already has (compared without case) is written as "qtmv_<name>" instead (then
// "qtmv_<name>_2", ...), e.g. a source field `cells` leaves ours as `qtmv_cells`.
// A site whose FID is OGRNullFID gets a null site_fid (site_a, site_b).
//
// area_m2 is the area of the region whose cell vertices are joined by geodesics (the cells then
// tile the ellipsoid exactly, so the areas add up to its area); each ring is taken with the
// region on its left, so a region around a pole gets its own area, not the rest of the Earth.
//
// GeoPackage: boundary_cells and cells (millions of polygons at the finer levels) are created
// without a spatial index (SPATIAL_INDEX=NO) unless options.layer_options names SPATIAL_INDEX:
// even filled at once (gpkg_rtree.hpp), an R-tree costs about 0.5 us a row, most of a row's own.
// The index can be added later with `ogrinfo out.gpkg -sql "SELECT CreateSpatialIndex('boundary_cells','geom')"`.
// regions and voronoi_edges keep GDAL's default (an R-tree). Every layer's rows go straight into
// its GeoPackage table (gpkg_rows.hpp) and its R-tree is packed at the end: the same rows as OGR
// features would give (and the same R-tree boxes), several times faster. The regions go through
// OGR features where OGR would change or mend a source value (plain_source_values: a field of
// another type than Integer, Integer64, Real or String, a subtype, a default value, text not in
// UTF-8 or longer than its field's width); the configuration option QTMV_GPKG_DIRECT_ROWS=NO sends
// every layer through OGR.
//
// Transactions of about 100 000 features where the driver has efficient ones (GeoPackage).
// On failure the dataset is closed and left as it is: the caller removes it (the pipeline
// writes to a temporary file).
#pragma once

#include <string>

#include "label/outline_cells.hpp"
#include "sites/site_table.hpp"
#include "write/cell_labels.hpp"

namespace qtmv::write {

/// Names accepted in VectorOptions::layers, in their default order.
extern const char* const kVectorLayerNames[4];

/// Checks a list of layer names: empty when every one is a layer of kVectorLayerNames and the
/// list is not empty, otherwise what is wrong ("no layer 'x': choose from regions, ...").
std::string check_layer_names(const std::vector<std::string>& layers);

/// Creates `path` with options.driver and writes the layers of options.layers: regions,
/// boundary_cells and voronoi_edges from `outlines` (the outline cells and cells per site of
/// label/outline_cells.hpp: memory and work follow the outlines), the cells layer from
/// `cell_tiles` (may be empty when that layer is not asked for). Site ids run 0 ..
/// table.sites.size() - 1 (std::invalid_argument otherwise, or std::logic_error for outline cells
/// that break their promises). Throws WriteError naming the destination, the layer and GDAL's
/// message when GDAL reports an error (creating, writing or closing), for an unknown layer name
/// or driver; Interrupted when options.progress returns false.
void write_vector(const std::string& path, const label::Outlines& outlines, const CellTileSource& cell_tiles,
                  const sites::SiteTable& table, const VectorOptions& options);

/// The same from dense labels of every cell (labels.site, and labels.boundary or flags computed
/// from the sites): for callers that hold them, and the tests.
void write_vector(const std::string& path, const CellLabels& labels, const sites::SiteTable& table,
                  const VectorOptions& options);

/// How a row whose geometry is empty (the region of a site without a cell) is written: with its
/// empty geometry, with a null one (the driver refuses or drops empties but keeps nulls), or not
/// at all (the driver holds neither: the caller names the rows in a warning). From the survey of
/// GDAL 3.6's drivers in docs/RELIABILITY.md, "Output drivers and what they cannot hold".
enum class EmptyRows { empty, null, left_out };

/// EmptyRows for the driver named `driver` (GDAL's short name).
EmptyRows empty_rows_of(const std::string& driver);

}  // namespace qtmv::write
