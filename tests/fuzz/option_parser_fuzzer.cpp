// The qtmvoronoi command line (parse_command_line): NUL-separated arguments. It returns options
// or throws UsageError; it never crashes. -sql @FILE is left out: it reads a named file.
#include <string>
#include <vector>

#include "fuzz_input.hpp"
#include "qtmvoronoi_core.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text = qtmv::fuzz::Input(data, size).rest();
  std::vector<std::string> args;
  for (std::size_t begin = 0; begin <= text.size();) {
    const std::size_t end = std::min(text.find('\0', begin), text.size());
    args.push_back(text.substr(begin, end - begin));
    if (!args.back().empty() && args.back()[0] == '@') return 0;
    begin = end + 1;
  }
  try {
    qtmv::qtmvoronoi::parse_command_line(args);
  } catch (const qtmv::qtmvoronoi::UsageError&) {
  }
  return 0;
}
