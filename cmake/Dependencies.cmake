# All third-party dependencies come from Debian 12 packages (launch_scripts/setup.sh installs them).
find_package(PkgConfig REQUIRED)
find_package(Threads REQUIRED)
find_package(Eigen3 3.4 REQUIRED NO_MODULE)
find_package(yaml-cpp REQUIRED)
find_package(spdlog REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
find_package(CLI11 REQUIRED)
find_package(fastcdr REQUIRED)
find_package(fastrtps 2.9 REQUIRED)
# Fast DDS 2.9.0 and 2.9.1 (Debian 12) race in secure discovery; services/dds carries a lock
# around it (fastdds_security_race.cpp), and tests/dds checks that the lock is reached.
if(fastrtps_VERSION VERSION_LESS 2.9.2)
  set(SYNDDS_FASTDDS_SECURITY_RACE ON)
else()
  set(SYNDDS_FASTDDS_SECURITY_RACE OFF)
endif()
find_package(embree 3 REQUIRED)
find_package(assimp 5 REQUIRED)  # Debian libassimp-dev: OBJ meshes of the rendered scene
find_package(OpenCV REQUIRED COMPONENTS core imgproc imgcodecs videoio)
pkg_check_modules(ODE REQUIRED IMPORTED_TARGET ode)
find_program(FASTDDSGEN fastddsgen REQUIRED)
# The Python binding is built for Debian's python3 (whose python3-numpy and python3-dev
# setup.sh installs), not whichever python3 comes first on PATH.
if(NOT DEFINED Python3_EXECUTABLE AND EXISTS /usr/bin/python3)
  set(Python3_EXECUTABLE /usr/bin/python3)
endif()
find_package(Python3 COMPONENTS Interpreter Development.Module REQUIRED)
set(PYBIND11_FINDPYTHON ON)
find_package(pybind11 2.10 CONFIG REQUIRED)
# libtorch (Debian's libtorch-dev): the PPO trainer and the learned-policy controller.
find_package(Torch REQUIRED)
if(SYNDDS_BUILD_TESTS)
  find_package(GTest REQUIRED)
endif()
