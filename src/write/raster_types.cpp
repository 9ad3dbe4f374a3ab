#include "write/raster_types.hpp"

#include <cpl_string.h>

#include <limits>

namespace qtmv::write {

GDALDataType raster_type_by_name(const std::string& name) {
  for (const char* t : kRasterDataTypes) {
    if (EQUAL(name.c_str(), t)) return GDALGetDataTypeByName(t);
  }
  return GDT_Unknown;
}

bool is_integer_type(GDALDataType type) { return type != GDT_Float32 && type != GDT_Float64; }

double largest_value(GDALDataType type) {
  switch (type) {
    case GDT_Byte: return 254;
    case GDT_UInt16: return 65534;
    case GDT_Int16: return 32767;
    case GDT_UInt32: return 4294967294.0;
    case GDT_Int32: return 2147483647.0;
    case GDT_Float32: return static_cast<double>(std::numeric_limits<float>::max());
    default: return std::numeric_limits<double>::max();
  }
}

bool fid_fits(std::int64_t fid, GDALDataType type) {
  if (fid < 0) return false;
  if (type == GDT_Float32) return static_cast<std::int64_t>(static_cast<float>(fid)) == fid;
  if (type == GDT_Float64) return static_cast<std::int64_t>(static_cast<double>(fid)) == fid;
  return static_cast<double>(fid) <= largest_value(type);
}

std::string range_text(GDALDataType type) {
  switch (type) {
    case GDT_Byte: return "0..254, 255 being nodata";
    case GDT_UInt16: return "0..65534, 65535 being nodata";
    case GDT_Int16: return "0..32767";
    case GDT_UInt32: return "0..4294967294, 4294967295 being nodata";
    case GDT_Int32: return "0..2147483647";
    case GDT_Float32: return "integers up to 16777216 = 2^24 and some larger ones";
    default: return "integers up to 2^53 and some larger ones";
  }
}

}  // namespace qtmv::write
