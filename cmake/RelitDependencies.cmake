# Finds relit's dependencies. All come from Debian's packages (scripts/setup.sh installs them).
find_package(OpenCL 1.2 REQUIRED)                  # OpenCL::OpenCL (the ICD loader)
find_package(nlohmann_json 3.10 CONFIG REQUIRED)   # nlohmann_json::nlohmann_json
find_package(Eigen3 3.3 CONFIG REQUIRED NO_MODULE) # Eigen3::Eigen (host math, test references)

if(RELIT_WITH_CLBLAST)
  find_package(CLBlast CONFIG REQUIRED)            # imported target `clblast` (no namespace)
endif()
if(RELIT_BUILD_APPS OR RELIT_BUILD_PYTHON)
  find_package(CLI11 CONFIG REQUIRED)              # CLI11::CLI11
endif()
if(RELIT_BUILD_TESTS)
  find_package(GTest CONFIG REQUIRED)
endif()
if(RELIT_BUILD_BENCH)
  find_package(benchmark CONFIG REQUIRED)
endif()
if(RELIT_BUILD_PYTHON OR RELIT_BUILD_TESTS)
  find_package(Python3 COMPONENTS Interpreter Development.Module REQUIRED)
endif()
if(RELIT_BUILD_PYTHON)
  find_package(pybind11 2.6 CONFIG REQUIRED)
endif()
