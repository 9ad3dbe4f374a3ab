// The pipeline's failure type, shared by its parts.
#pragma once

#include <stdexcept>

namespace qtmv {

/// A failed run; what() says why, naming the file. The destination is untouched.
class VoronoiError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace qtmv
