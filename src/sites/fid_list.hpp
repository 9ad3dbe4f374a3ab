// The FIDs a warning names: all of them counted, the first few listed.
#pragma once

#include <cstdint>
#include <string>

namespace qtmv::sites {

class FidList {
 public:
  /// FIDs listed in the text; the rest are only counted.
  static constexpr std::uint64_t kListed = 10;

  void add(std::int64_t fid) {
    if (++count_ <= kListed) listed_ += (listed_.empty() ? "" : ", ") + std::to_string(fid);
  }
  std::uint64_t count() const { return count_; }
  /// "3, 17, 40", or "1, 2, ..., 10, ..." when more were added than are listed.
  std::string text() const { return listed_ + (count_ > kListed ? ", ..." : ""); }

 private:
  std::uint64_t count_ = 0;
  std::string listed_;
};

}  // namespace qtmv::sites
