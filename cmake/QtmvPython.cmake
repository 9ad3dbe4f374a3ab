# The Python package's prerequisites (python/): Debian's own python3 (its packages, its
# dist-packages), its development files, numpy and pybind11 (Debian 12: python3-dev, python3-numpy,
# pybind11-dev). Sets QTMV_HAVE_PYTHON, and says why when the package is left out.
set(QTMV_HAVE_PYTHON OFF)
if(NOT QTMV_WITH_PYTHON)
  return()
endif()
if(NOT QTMV_WITH_GDAL)
  message(STATUS "qtmvoronoi: the Python package is left out: it binds the pipeline, which needs QTMV_WITH_GDAL")
  return()
endif()
if(CMAKE_CXX_FLAGS MATCHES "sanitize" OR QTMV_FUZZ)
  message(STATUS "qtmvoronoi: the Python package is left out of a sanitizer build (python3 loads no sanitizer runtime)")
  return()
endif()

# The system's python (Debian: /usr/bin/python3), not the first python3 on the PATH (a pyenv's, a
# virtualenv's): the package goes into its dist-packages and uses its packages.
if(NOT DEFINED Python3_EXECUTABLE AND EXISTS /usr/bin/python3)
  set(Python3_EXECUTABLE /usr/bin/python3)
endif()
find_package(Python3 COMPONENTS Interpreter Development.Module NumPy)
if(NOT Python3_FOUND)
  message(STATUS "qtmvoronoi: the Python package is left out: python3 with its development files and numpy "
                 "not found (Debian: apt-get install python3-dev python3-numpy)")
  return()
endif()
# pybind11 takes the Python3 found above (its FindPython mode).
find_package(pybind11 CONFIG QUIET)
if(NOT pybind11_FOUND)
  message(STATUS "qtmvoronoi: the Python package is left out: pybind11 not found (Debian: apt-get install pybind11-dev)")
  return()
endif()
set(QTMV_HAVE_PYTHON ON)
message(STATUS "qtmvoronoi: Python package for ${Python3_EXECUTABLE} (Python ${Python3_VERSION}, "
               "numpy ${Python3_NumPy_VERSION}, pybind11 ${pybind11_VERSION})")
