# The readers' benchmark (needs GDAL), included from tools/bench/CMakeLists.txt:
#   if(TARGET qtmv::sites AND EXISTS "${CMAKE_CURRENT_SOURCE_DIR}/sites.cmake")
#     include(sites.cmake)
#   endif()
add_executable(sites_bench ${CMAKE_CURRENT_LIST_DIR}/sites_bench.cpp)
target_link_libraries(sites_bench PRIVATE qtmv::sites)
