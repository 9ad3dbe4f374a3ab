// The raster bands' data types (-ot): which values each holds, for the writer's checks of FIDs
// before writing and of distances while writing.
#pragma once

#include <gdal.h>

#include <cstdint>
#include <string>

namespace qtmv::write {

/// The data types of -ot, as GDAL names them.
constexpr const char* kRasterDataTypes[] = {"Byte", "UInt16", "Int16", "UInt32", "Int32", "Float32", "Float64"};

/// The type of -ot's name (any case), or GDT_Unknown.
GDALDataType raster_type_by_name(const std::string& name);

/// Whether `type` is an integer type (distances are then rounded to whole metres).
bool is_integer_type(GDALDataType type);

/// The largest value a band of `type` holds as data (below the nodata of an unsigned type).
double largest_value(GDALDataType type);

/// Whether FID `fid` is stored exactly in a band of `type`.
bool fid_fits(std::int64_t fid, GDALDataType type);

/// The values `type` holds, for messages: "0..65534, 65535 being nodata".
std::string range_text(GDALDataType type);

}  // namespace qtmv::write
