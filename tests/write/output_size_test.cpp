// The output's size before any work: the estimates and the refusal.
#include "write/output_size.hpp"

#include <cpl_conv.h>
#include <gtest/gtest.h>

#include <string>

#include "../test_temp_dir.hpp"
#include "common/config_option.hpp"

namespace qtmv::write {
namespace {

TEST(OutputSize, RasterIsPixelsTimesBandsTimesBytes) {
  RasterOptions o;
  o.layout = RasterOptions::Layout::lonlat;
  o.width = o.height = 1000000;
  const OutputSize big = estimate_raster_size(4, o, true);
  EXPECT_EQ(big.bytes, 12000000000000ull);  // 10^12 pixels, 3 bands of 4 bytes (Float32 by default)
  EXPECT_EQ(big.what, "1000000 x 1000000 pixels, 3 bands of Float32");
  EXPECT_EQ(big.smaller, "fewer pixels (-tr, -ts)");
  const OutputSize ints = estimate_raster_size(4, o, false);
  EXPECT_EQ(ints.bytes, 8000000000000ull);  // 2 bands of Int32
  EXPECT_EQ(ints.what, "1000000 x 1000000 pixels, 2 bands of Int32");
  // The QTM-coded raster: (2^(L+1) - 1) x 8 * 2^L pixels.
  const OutputSize qtm = estimate_raster_size(9, RasterOptions{}, true);
  EXPECT_EQ(qtm.bytes, 1023ull * 4096 * 12);
  EXPECT_EQ(qtm.smaller, "a lower -level");
  // -ot: the named type.
  o.data_type = "float64";
  EXPECT_EQ(estimate_raster_size(4, o, true).bytes, 24000000000000ull);
  o.data_type = "Byte";
  EXPECT_EQ(estimate_raster_size(4, o, true).what, "1000000 x 1000000 pixels, 3 bands of Byte");
  o.data_type = "Int8";
  EXPECT_THROW(estimate_raster_size(4, o, true), WriteError);
}

TEST(OutputSize, VectorCountsTheCellsLayerOnly) {
  VectorOptions o;
  o.driver = "GPKG";
  EXPECT_EQ(estimate_vector_size(9, o).bytes, 0u);  // regions, boundary_cells, voronoi_edges
  o.layers.push_back("cells");
  const OutputSize cells = estimate_vector_size(9, o);
  EXPECT_EQ(cells.bytes, (8ull << 18) * 150);
  EXPECT_EQ(cells.what, "2097152 rows of about 150 bytes");
  o.driver = "GeoJSON";
  EXPECT_EQ(estimate_vector_size(9, o).bytes, (8ull << 18) * 300);
  EXPECT_EQ(bytes_per_cell_row("ESRI Shapefile"), 200u);
}

TEST(OutputSize, ExpectedVectorBytesAddTheOutlinesAndChooseTheSqlitePage) {
  VectorOptions o;
  o.layers = {"regions", "voronoi_edges"};
  EXPECT_EQ(expected_vector_bytes(10, o, 1000), 1000 * kBytesPerOutlineCell);
  o.layers = {"cells"};
  EXPECT_EQ(expected_vector_bytes(10, o, 1000), estimate_vector_size(10, o).bytes);
  o.layers = {"cells", "boundary_cells"};
  EXPECT_EQ(expected_vector_bytes(10, o, 1000), estimate_vector_size(10, o).bytes + 1000 * kBytesPerOutlineCell);
  EXPECT_EQ(sqlite_page_size(kLargeSqliteFileBytes - 1), 0u);
  EXPECT_EQ(sqlite_page_size(kLargeSqliteFileBytes), kLargeSqlitePageSize);
  EXPECT_EQ(sqlite_page_size(std::uint64_t{1} << 40), 65536u);
}

TEST(OutputSize, BytesInDecimalUnits) {
  EXPECT_EQ(format_bytes(24e12), "24.0 TB");
  EXPECT_EQ(format_bytes(80.1e9), "80.1 GB");
  EXPECT_EQ(format_bytes(307200), "307.2 kB");
  EXPECT_EQ(format_bytes(512), "512 bytes");
}

TEST(OutputSize, RefusedWhenLargerThanTheFreeSpaceUnlessToldNot) {
  const std::string dir = qtmv::test::process_temp_dir();
  const std::string dst = dir + "/out.tif";
  const OutputSize size{2000, "10 x 10 pixels, 3 bands of Float64", "a lower -level"};
  qtmv::set_config_lookup(&CPLGetConfigOption);  // the fault switch as a GDAL configuration option, as in the tool
  {
    CPLConfigOptionSetter disk("QTMV_FAULT_DISK_FREE_BYTES", "1000", false);
    try {
      check_disk_space(dst, size, "raster");
      FAIL() << "not refused";
    } catch (const WriteError& e) {
      EXPECT_EQ(std::string(e.what()), "'" + dst + "': the raster takes about 2.0 kB uncompressed (10 x 10 pixels, 3 "
                                       "bands of Float64) and '" + dir + "' has 1.0 kB free: choose a lower -level; for "
                                       "an output that compresses well or is sparse, add --config "
                                       "CHECK_DISK_FREE_SPACE NO");
    }
    CPLConfigOptionSetter off("CHECK_DISK_FREE_SPACE", "NO", false);
    EXPECT_NO_THROW(check_disk_space(dst, size, "raster"));
  }
  {
    CPLConfigOptionSetter disk("QTMV_FAULT_DISK_FREE_BYTES", "2000", false);
    EXPECT_NO_THROW(check_disk_space(dst, size, "raster"));  // fits exactly
    EXPECT_NO_THROW(check_disk_space("/vsimem/out.tif", size, "raster"));
    EXPECT_NO_THROW(check_disk_space(dir + "/no/such/dir/out.tif", OutputSize{1u << 30, "", ""}, "raster"));
  }
  // The real free space: nobody has an exabyte.
  EXPECT_THROW(check_disk_space(dst, OutputSize{4000000000000000000ull, "a lot", "less"}, "raster"), WriteError);
}

}  // namespace
}  // namespace qtmv::write
