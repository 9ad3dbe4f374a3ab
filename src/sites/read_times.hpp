// The times of the read's parts: the figures of the read trace (QTMV_TRACE=read, for tuning) and
// the summary's rasterise time.
#pragma once

#include <chrono>

namespace qtmv::sites {

/// Seconds since `start`.
inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// The times of the read's parts, summed over its layers and steps (seconds). The reading
/// thread reads and settles the features while the other threads examine, build and append
/// those read before: the latter are thread time, summed over the threads.
struct ReadTimes {
  bool time_jobs = false;    ///< whether each job is timed (the read is traced)
  double read_s = 0;         ///< GDAL's reads of the features (the reading thread)
  double settled_s = 0;      ///< features reported and made jobs in feature order (the reading thread)
  double examined_s = 0;     ///< features examined (thread time)
  double built_s = 0;        ///< sites traced and filled (thread time)
  double longest_job_s = 0;  ///< the longest job (timed only when the read is traced)
  double appended_s = 0;     ///< built sites appended to the geometry (thread time)
  /// The time the read's steps took beyond the reading thread's share (the work that reading
  /// did not hide: tracing, filling, appending), and the claims.
  std::chrono::steady_clock::duration rasterise{};
};

}  // namespace qtmv::sites
