// GDAL's error messages caught while a piece of work runs, for the readers and the writers.
//
// GDAL 3.6 reports some failures only through its error handler (GDALClose returns nothing, a
// GeoPackage reports a bad -where while reading), so every part that drives GDAL installs one of
// these for the span of its work and turns the failures into its own error, naming the file.
#pragma once

#include <cpl_error.h>

#include <algorithm>
#include <string>
#include <vector>

namespace qtmv::gdal {

/// Installs `handler` with `user_data` on top of GDAL's error handlers (debug output passes by).
inline void push_handler(CPLErrorHandler handler, void* user_data) {
  CPLPushErrorHandlerEx(handler, user_data);
  CPLSetCurrentErrorHandlerCatchDebug(FALSE);
}

/// From inside `handler` (the top one): raises a message again for the handler below it. GDAL
/// 3.6 has no CPLCallPreviousHandler: step aside, raise, and come back.
inline void raise_below(CPLErrorHandler handler, void* user_data, CPLErr type, CPLErrorNum number,
                        const std::string& text) {
  CPLPopErrorHandler();
  CPLError(type, number, "%s", text.c_str());
  push_handler(handler, user_data);
}

class ErrorCapture {
 public:
  enum class Warnings {
    keep,     ///< kept with the failures, for take()
    pass_on,  ///< handed on at once to the handler below this one
  };

  explicit ErrorCapture(Warnings warnings = Warnings::keep) : warnings_(warnings) {
    CPLErrorReset();
    push_handler(&ErrorCapture::handle, this);
  }
  ~ErrorCapture() { CPLPopErrorHandler(); }
  ErrorCapture(const ErrorCapture&) = delete;
  ErrorCapture& operator=(const ErrorCapture&) = delete;

  /// Whether a failure (CE_Failure or CE_Fatal) came since the last take().
  bool failed() const { return failed_; }

  /// The messages kept since the last take(): the first kMostShown distinct ones joined with
  /// "; " and a count of the rest (empty when there were none). Forgets them.
  std::string take() {
    std::vector<std::string> distinct;
    for (const std::string& m : messages_) {
      if (std::find(distinct.begin(), distinct.end(), m) == distinct.end()) distinct.push_back(m);
    }
    std::string out;
    for (std::size_t k = 0; k < std::min(distinct.size(), kMostShown); ++k) out += (k ? "; " : "") + distinct[k];
    if (distinct.size() > kMostShown) out += "; (" + std::to_string(distinct.size() - kMostShown) + " more)";
    messages_.clear();
    failed_ = false;
    return out;
  }

 private:
  static constexpr std::size_t kMostShown = 3;


  static void CPL_STDCALL handle(CPLErr type, CPLErrorNum number, const char* message) {
    auto* self = static_cast<ErrorCapture*>(CPLGetErrorHandlerUserData());
    const std::string text = message ? message : "";
    if (type >= CE_Failure) {
      self->failed_ = true;
      self->messages_.push_back(text);
    } else if (self->warnings_ == Warnings::keep) {
      self->messages_.push_back(text);
    } else {
      raise_below(&ErrorCapture::handle, self, type, number, text);
    }
  }

  Warnings warnings_;
  std::vector<std::string> messages_;
  bool failed_ = false;
};

}  // namespace qtmv::gdal
