// The times of the read's parts: the figures of the read trace (QTMV_TRACE=read, for tuning) and
// the summary's rasterise time.
#pragma once

#include <chrono>

namespace qtmv::sites {

/// Seconds since `start`.
inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

/// The times of the read's parts, summed over its layers and batches (seconds).
struct ReadTimes {
  bool time_jobs = false;    ///< whether each job is timed (the read is traced)
  double examined_s = 0;     ///< features examined on all threads
  double built_s = 0;        ///< sites traced and filled on all threads
  double longest_job_s = 0;  ///< the longest job (timed only when the read is traced)
  double appended_s = 0;     ///< built sites appended to the geometry
  std::chrono::steady_clock::duration rasterise{};  ///< tracing, filling and claims, within the read
};

}  // namespace qtmv::sites
