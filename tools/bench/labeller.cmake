# The labeller's benchmark (core-only: no GDAL), included from tools/bench/CMakeLists.txt.
add_executable(qtmv_bench ${CMAKE_CURRENT_LIST_DIR}/qtmv_bench.cpp)
target_link_libraries(qtmv_bench PRIVATE qtmv::label)
