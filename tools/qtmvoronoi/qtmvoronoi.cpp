// qtmvoronoi: spherical Voronoi diagrams on the QTM grid (see man/qtmvoronoi.pod). The command
// line is in qtmvoronoi_core.cpp, the work in the library's run_voronoi() (src/voronoi.hpp).
#include "qtmvoronoi_core.hpp"

int main(int argc, char** argv) { return qtmv::qtmvoronoi::qtmvoronoi_main(argc, argv); }
