#include "pipeline/staged_output.hpp"

#include <utility>

#include "gdal/error_capture.hpp"

namespace qtmv::pipeline {

void replace_all(std::string& text, const std::string& from, const std::string& to) {
  if (from.empty()) return;
  for (std::size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size())) {
    text.replace(at, from.size(), to);
  }
}

RenameInMessages::RenameInMessages(std::string from, std::string to) : from_(std::move(from)), to_(std::move(to)) {
  gdal::push_handler(&RenameInMessages::handle, this);
}

RenameInMessages::~RenameInMessages() { CPLPopErrorHandler(); }

void CPL_STDCALL RenameInMessages::handle(CPLErr type, CPLErrorNum number, const char* message) {
  auto* self = static_cast<RenameInMessages*>(CPLGetErrorHandlerUserData());
  std::string text = message ? message : "";
  replace_all(text, self->from_, self->to_);
  gdal::raise_below(&RenameInMessages::handle, self, type, number, text);
}

}  // namespace qtmv::pipeline
