// Reads fixed-size values off the front of a fuzzer's input, zeros once it runs out (as
// FuzzedDataProvider does, without needing clang's header in the replay build).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

namespace qtmv::fuzz {

class Input {
 public:
  Input(const std::uint8_t* data, std::size_t size) : data_(data), size_(size) {}
  template <class T>
  T take() {
    T value{};
    const std::size_t n = size_ < sizeof(T) ? size_ : sizeof(T);
    std::memcpy(&value, data_, n);
    data_ += n;
    size_ -= n;
    return value;
  }
  /// What is left, as text.
  std::string rest() const { return std::string(reinterpret_cast<const char*>(data_), size_); }
  const std::uint8_t* data() const { return data_; }
  std::size_t size() const { return size_; }

 private:
  const std::uint8_t* data_;
  std::size_t size_;
};

}  // namespace qtmv::fuzz
