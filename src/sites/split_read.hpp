// A layer's features read by several GDAL datasets at once (issue 37: GDAL's CSV parser is one
// thread, 1.5-2.5 s a million rows): a CSV file is cut at line starts into byte ranges, each
// range read on a thread of its own by GDAL's CSV driver as an in-memory CSV (the header line
// and the range's lines, the same name, its .csvt and .prj beside it, the same open options and
// -where), and the features handed on in the order, with the FIDs, and with the GDAL messages at
// the places, of one sequential read. Only where that is provably the same read: no quote in the
// data (a quoted field may hold a line break), no carriage return but before a line feed, no NUL,
// a header line that a header-only part reads with the layer's own definition and no feature,
// only open options that apply line by line, no -sql, no FID in -where. A GeoPackage table is
// read in ranges of FIDs (rowids), each on its own connection, in rowid order as its whole read
// (a full scan) is; not with -where (SQLite may read it in an index's order) nor a view. Else the
// layer is read as one sequence, and the read trace says why.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include <ogrsf_frmts.h>

#include "sites/ogr_source.hpp"
#include "sites/site_options.hpp"

namespace qtmv::sites {

/// The most GDAL datasets that read one layer at once (a split read's parts, a tile selection's
/// connections). On 32 cores (bench/RESULTS.md, session 26), 1M points, teams of 4 and 8: a
/// GeoPackage read by 4 or 8 in 0.64-0.80 s, by 16 or 32 in 0.83-1.05 s (more connections than the
/// reading thread can take features from); a CSV by 8 or 16 in 0.76-0.88 s, by 4 in 0.92-1.06 s,
/// by 32 in 0.88-1.10 s.
constexpr std::size_t kMostReaders = 8;

class SplitRead {
 public:
  /// The split read of layer `layer_number` of `source` (options.where is applied to every part)
  /// on up to `threads` threads (at most 8: more read no faster), or null when the layer is to be
  /// read as one sequence. Either
  /// way a QTMV_TRACE=read line says so, and why. `where_from` names the file and layer.
  static std::unique_ptr<SplitRead> open(const OgrSource& source, std::size_t layer_number,
                                         const ReadOptions& options, int threads, const std::string& where_from);
  /// Stops the parts' threads (each at its next feature) and waits for them.
  ~SplitRead();
  SplitRead(const SplitRead&) = delete;
  SplitRead& operator=(const SplitRead&) = delete;

  /// The next feature in the sequential read's order, with its FID; null at the end (or after a
  /// part's reading failed, as GDAL's sequential read ends there). GDAL's messages of reading it
  /// are raised again here, on the calling thread, for the caller's error handler.
  OGRFeatureUniquePtr next();
  /// The share of the file's lines handed on so far (0..1), for the progress.
  double fraction_done() const;

  struct Impl;

 private:
  explicit SplitRead(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace qtmv::sites
