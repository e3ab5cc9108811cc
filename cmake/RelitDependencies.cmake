# Finds relit's dependencies. All come from Debian's packages (scripts/setup.sh installs them).
find_package(OpenCL 1.2 REQUIRED)                  # OpenCL::OpenCL (the ICD loader)
find_package(nlohmann_json 3.10 CONFIG REQUIRED)   # nlohmann_json::nlohmann_json
find_package(Eigen3 3.3 CONFIG REQUIRED NO_MODULE) # Eigen3::Eigen (host math, test references)

if(RELIT_WITH_OPENIMAGEIO)
  # Images (EXR, PNG, HDR) for datasets and environment maps.
  find_package(OpenImageIO CONFIG REQUIRED)          # OpenImageIO::OpenImageIO
  # Debian 12's OIIO target lists /usr/include/opencv4, which exists only with libopencv-dev: drop it.
  foreach(_p INTERFACE_INCLUDE_DIRECTORIES INTERFACE_SYSTEM_INCLUDE_DIRECTORIES)
    get_target_property(_v OpenImageIO::OpenImageIO ${_p})
    if(_v)
      list(FILTER _v EXCLUDE REGEX "opencv4")
      set_target_properties(OpenImageIO::OpenImageIO PROPERTIES ${_p} "${_v}")
    endif()
  endforeach()
endif()
if(RELIT_WITH_OPENVDB)
  # OpenVDB (fog volume import) ships only a Find module, in an architecture-specific folder on Debian.
  foreach(_dir "/usr/lib/${CMAKE_LIBRARY_ARCHITECTURE}/cmake/OpenVDB" "/usr/lib/cmake/OpenVDB"
               "/usr/local/lib/cmake/OpenVDB")
    if(EXISTS "${_dir}/FindOpenVDB.cmake")
      list(APPEND CMAKE_MODULE_PATH "${_dir}")
      break()
    endif()
  endforeach()
  # FindOpenVDB sets BUILD_SHARED_LIBS (and Boost_USE_STATIC_LIBS) in the caller's scope: keep ours.
  set(_relit_shared_libs_defined FALSE)
  if(DEFINED BUILD_SHARED_LIBS)
    set(_relit_shared_libs_defined TRUE)
    set(_relit_shared_libs "${BUILD_SHARED_LIBS}")
  endif()
  find_package(OpenVDB REQUIRED)                     # OpenVDB::openvdb
  if(_relit_shared_libs_defined)
    set(BUILD_SHARED_LIBS "${_relit_shared_libs}")
  else()
    unset(BUILD_SHARED_LIBS)
  endif()
endif()

# MPI for data parallelism over several devices and machines (docs/scaling.md); relit builds without it.
set(RELIT_MPI_FOUND OFF)
if(RELIT_WITH_MPI)
  find_package(MPI COMPONENTS CXX)                 # MPI::MPI_CXX
  if(MPI_CXX_FOUND)
    set(RELIT_MPI_FOUND ON)
  else()
    message(STATUS "relit: no MPI found: building without data parallelism (install libopenmpi-dev openmpi-bin)")
  endif()
endif()

if(RELIT_BUILD_APPS OR RELIT_BUILD_PYTHON)
  find_package(CLI11 CONFIG REQUIRED)              # CLI11::CLI11
endif()
if(RELIT_BUILD_TESTS)
  find_package(GTest CONFIG REQUIRED)
endif()
if(RELIT_BUILD_BENCH AND RELIT_WITH_CLBLAST)
  find_package(CLBlast CONFIG REQUIRED)            # imported target `clblast` (no namespace): bench_mlp's peer
endif()
if(RELIT_BUILD_PYTHON)
  find_package(Python3 COMPONENTS Interpreter Development.Module REQUIRED)
endif()
if(RELIT_BUILD_PYTHON)
  find_package(pybind11 2.6 CONFIG REQUIRED)
endif()
