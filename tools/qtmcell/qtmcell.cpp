// qtmcell: the QTM grid on the command line (see man/qtmcell.pod). All the work is in
// qtmcell_core.cpp, where the tests reach it.
#include <iostream>
#include <string>
#include <vector>

#include "qtmcell_core.hpp"

int main(int argc, char** argv) {
  std::ios::sync_with_stdio(false);  // pipelines of millions of lines; cin stays tied to cout
  const std::vector<std::string> args(argv + 1, argv + argc);
  return qtmv::qtmcell::qtmcell_main(args, std::cin, std::cout, std::cerr);
}
