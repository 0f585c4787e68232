# Every dependency is a Debian 12 package installed by tools/run.sh.
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(Ceres 2.1 REQUIRED)
find_package(yaml-cpp REQUIRED)
find_package(glog REQUIRED)
find_package(Threads REQUIRED)
# Debian ships GeographicLib's find module outside CMake's default module path.
list(APPEND CMAKE_MODULE_PATH /usr/share/cmake/geographiclib)
find_package(GeographicLib REQUIRED)
# Bag import: the generic decompressors and SQLite; the bag formats themselves are parsed
# in src/import/.
find_package(BZip2 REQUIRED)
find_package(SQLite3 REQUIRED)
find_library(AUTOCAL_LZ4_LIBRARY lz4 REQUIRED)
find_library(AUTOCAL_ZSTD_LIBRARY zstd REQUIRED)
