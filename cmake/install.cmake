# SPDX-License-Identifier: MIT
# Copyright (c) obsynth authors
#
# Install rules and the CMake package for obsynth (included at the end of the top-level
# CMakeLists.txt).
#
#   cmake --install build --prefix /opt/obsynth
#
# installs
#   bin/obsynth                                   the synthesizer            (component generator)
#   include/obsynth/*.hpp, c/*.h                  the header-only runtime    (component runtime)
#   lib/cmake/obsynth/obsynthConfig.cmake,
#     obsynthConfigVersion.cmake,
#     obsynthRuntimeTargets.cmake                 obsynth::runtime           (component runtime)
#     obsynthGeneratorTargets*.cmake              obsynth::obsynth           (component generator)
#     ObsynthGenerate.cmake                       obsynth_add_observer()     (component runtime)
#
# Consumers: find_package(obsynth 0.1 REQUIRED) then obsynth_add_observer(...) (see
# cmake/ObsynthGenerate.cmake and examples/seed003_firmware). A firmware-only install of the
# MIT runtime without the GPL synthesizer: cmake --install build --component runtime.

include_guard(GLOBAL)
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(OBSYNTH_INSTALL_CMAKEDIR "${CMAKE_INSTALL_LIBDIR}/cmake/obsynth"
    CACHE STRING "Where to install the obsynth CMake package files (relative to the prefix)")
# Must match the $<INSTALL_INTERFACE:include> of obsynth_runtime (top-level CMakeLists.txt).
set(_obsynth_include_dir include)

# obsynth_add_observer() in the build tree itself: the executable is the obsynth target, the
# runtime obsynth_runtime (alias obsynth::runtime).
include("${CMAKE_CURRENT_LIST_DIR}/ObsynthGenerate.cmake")
if(TARGET obsynth AND NOT TARGET obsynth::obsynth)
  add_executable(obsynth::obsynth ALIAS obsynth)
endif()

# --- the synthesizer ---------------------------------------------------------------------------
install(TARGETS obsynth
        EXPORT obsynthGeneratorTargets
        RUNTIME DESTINATION "${CMAKE_INSTALL_BINDIR}" COMPONENT generator)
install(EXPORT obsynthGeneratorTargets
        NAMESPACE obsynth::
        FILE obsynthGeneratorTargets.cmake
        DESTINATION "${OBSYNTH_INSTALL_CMAKEDIR}"
        COMPONENT generator)

# --- the runtime -------------------------------------------------------------------------------
set_target_properties(obsynth_runtime PROPERTIES EXPORT_NAME runtime)
install(TARGETS obsynth_runtime EXPORT obsynthRuntimeTargets)
install(DIRECTORY "${CMAKE_CURRENT_LIST_DIR}/../runtime/obsynth/"
        DESTINATION "${_obsynth_include_dir}/obsynth"
        COMPONENT runtime
        FILES_MATCHING PATTERN "*.hpp" PATTERN "*.h")
install(EXPORT obsynthRuntimeTargets
        NAMESPACE obsynth::
        FILE obsynthRuntimeTargets.cmake
        DESTINATION "${OBSYNTH_INSTALL_CMAKEDIR}"
        COMPONENT runtime)

# --- package configuration ---------------------------------------------------------------------
configure_package_config_file(
  "${CMAKE_CURRENT_LIST_DIR}/obsynthConfig.cmake.in"
  "${CMAKE_CURRENT_BINARY_DIR}/obsynth-package/obsynthConfig.cmake"
  INSTALL_DESTINATION "${OBSYNTH_INSTALL_CMAKEDIR}")
# 0.x: minor versions may break the generated-code contract. The runtime is header-only and the
# executable is a host tool, so a 64-bit host install serves 32-bit (e.g. Cortex-M) builds too.
write_basic_package_version_file(
  "${CMAKE_CURRENT_BINARY_DIR}/obsynth-package/obsynthConfigVersion.cmake"
  VERSION "${obsynth_VERSION}"
  COMPATIBILITY SameMinorVersion
  ARCH_INDEPENDENT)
install(FILES
          "${CMAKE_CURRENT_BINARY_DIR}/obsynth-package/obsynthConfig.cmake"
          "${CMAKE_CURRENT_BINARY_DIR}/obsynth-package/obsynthConfigVersion.cmake"
          "${CMAKE_CURRENT_LIST_DIR}/ObsynthGenerate.cmake"
        DESTINATION "${OBSYNTH_INSTALL_CMAKEDIR}"
        COMPONENT runtime)
