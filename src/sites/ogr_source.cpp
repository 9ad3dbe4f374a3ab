#include "sites/ogr_source.hpp"

#include <cpl_string.h>
#include <cpl_vsi.h>
#include <sys/stat.h>

#include <cstddef>

#include "common/host_info.hpp"

namespace qtmv::sites {

namespace {

/// Opens `dataset_name` as a vector dataset; its warnings go to options.messages.
GDALDatasetUniquePtr open_dataset(const std::string& dataset_name, const ReadOptions& options,
                                  gdal::ErrorCapture& errors) {
  // A FIFO, socket or device would block GDAL's open for ever (a FIFO without a writer) or be
  // read past its end: only files and directories are opened by name.
  struct stat local;
  if (dataset_name.rfind("/vsi", 0) != 0 && stat(dataset_name.c_str(), &local) == 0 && !S_ISREG(local.st_mode) &&
      !S_ISDIR(local.st_mode)) {
    throw ReadError("cannot open '" + dataset_name + "': not a regular file or directory (" +
                    special_file_kind(local.st_mode) +
                    "); for standard input use /vsistdin/");
  }
  GDALDatasetUniquePtr dataset = open_vector(dataset_name, options.open_options);
  if (!dataset) {
    VSIStatBufL stat;
    if (VSIStatL(dataset_name.c_str(), &stat) != 0) {
      // In /vsizip/ and the like, a file that is not an archive of that kind looks missing too.
      const bool virtual_path = dataset_name.rfind("/vsi", 0) == 0;
      throw ReadError(with_gdal_message(
          "cannot open '" + dataset_name + "': no such file" + (virtual_path ? ", or not a readable archive" : ""),
          errors.take()));
    }
    throw ReadError(with_gdal_message("cannot open '" + dataset_name + "' as a vector dataset", errors.take()));
  }
  // The open's warnings (an -oo the driver does not know, say) would be dropped below: pass them on.
  if (const std::string warnings = errors.take(); !warnings.empty()) {
    tell(options.messages, Severity::warning, "'" + dataset_name + "': GDAL: " + warnings);
  }
  return dataset;
}

/// Finds the layers to read in `source`'s dataset.
void find_layers(OgrSource& source, const ReadOptions& options, gdal::ErrorCapture& errors) {
  const std::string& dataset_name = source.name;
  GDALDataset* const dataset = source.dataset.get();
  std::vector<SourceLayer>& layers = source.layers;
  if (!options.sql.empty()) {
    errors.take();
    OGRLayer* layer = dataset->ExecuteSQL(options.sql.c_str(), nullptr, options.dialect.empty() ? nullptr : options.dialect.c_str());
    if (!layer) {
      throw ReadError(with_gdal_message("'" + dataset_name + "': -sql failed: " + options.sql, errors.take()));
    }
    source.sql_result.reset(layer, [dataset](OGRLayer* l) { dataset->ReleaseResultSet(l); });
    layers.push_back({layer, "(-sql result)"});
  } else if (!options.layers.empty()) {
    for (const std::string& name : options.layers) {
      OGRLayer* layer = dataset->GetLayerByName(name.c_str());
      if (!layer) {
        std::string names;
        for (int k = 0; k < dataset->GetLayerCount(); ++k) names += std::string(k ? ", " : "") + dataset->GetLayer(k)->GetName();
        throw ReadError("'" + dataset_name + "' has no layer '" + name + "'; its layers: " + (names.empty() ? "(none)" : names));
      }
      // Names differ, layers may not: a GeoPackage's are case-insensitive (-l towns -l TOWNS).
      for (std::size_t k = 0; k < layers.size(); ++k) {
        if (layers[k].layer == layer) {
          throw ReadError("'" + dataset_name + "': -l '" + options.layers[k] + "' and -l '" + name +
                          "' name the same layer '" + layer->GetName() + "': name it once");
        }
      }
      layers.push_back({layer, layer->GetName()});
    }
  } else {
    if (dataset->GetLayerCount() == 0) throw ReadError("'" + dataset_name + "' has no layer");
    layers.push_back({dataset->GetLayer(0), dataset->GetLayer(0)->GetName()});
  }
}

}  // namespace

std::string OgrSource::describe() const {
  std::string where_all = "'" + name + "', layer" + (layers.size() > 1 ? "s " : " ");
  for (std::size_t k = 0; k < layers.size(); ++k) where_all += (k ? ", '" : "'") + layers[k].name + "'";
  return where_all;
}

bool OgrSource::plain_file(std::uint64_t* bytes) const {
  struct stat local {};
  if (name.rfind("/vsi", 0) == 0 || ::stat(name.c_str(), &local) != 0 || !S_ISREG(local.st_mode)) return false;
  if (bytes) *bytes = static_cast<std::uint64_t>(local.st_size);
  return true;
}

GDALDatasetUniquePtr open_vector(const std::string& dataset_name, const std::vector<std::string>& open_options,
                                 const char* const* drivers) {
  CPLStringList list;
  for (const std::string& option : open_options) list.AddString(option.c_str());
  return GDALDatasetUniquePtr(
      GDALDataset::Open(dataset_name.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, drivers, list.List()));
}

OgrSource open_source(const std::string& dataset_name, const ReadOptions& options, gdal::ErrorCapture& errors) {
  OgrSource source;
  source.name = dataset_name;
  source.dataset = open_dataset(dataset_name, options, errors);
  find_layers(source, options, errors);
  return source;
}

}  // namespace qtmv::sites
