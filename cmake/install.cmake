# SPDX-License-Identifier: MIT
# ---- installing btfkit: `cmake --install build/release --prefix P` (docs/library.md) -------------
# Included at the end of CMakeLists.txt, once every target exists. What goes where:
#
#   P/bin/btf                              the command                              runtime
#   P/lib/btfkit/libbtfkit_images.so       the image module (core/image_module.h)   runtime
#   P/lib/libbtfkit.a                      the library (.so with -DBTFKIT_SHARED=ON: runtime)
#   P/include/btf/...                      btf/btf.h and the headers it includes    devel
#   P/lib/cmake/btfkit/                    find_package(btfkit CONFIG): btfkit::btfkit
#   P/lib/pkgconfig/btfkit.pc              pkg-config --cflags --libs btfkit
#   P/lib/python3.11/dist-packages/btfkit  the Python module                        python
#
# A plain `cmake --install` installs runtime and devel. The Python module is left to an explicit
# `--component python`: it belongs in a Python's own site folder, which a prefix for the library
# need not be. That component also holds the libraries the module loads (the image module, and a
# shared libbtfkit), so that it works on its own.
#
# CTest's Install.consumer and Install.python (tests/install_consumer.sh) install into a temporary
# prefix and build and run examples/cpp and an import of the Python module against it.

include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(BTFKIT_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/btfkit)

# ---- the installed target --------------------------------------------------------------------
# btfkit's usage requirements name this tree: the include folder src/, and BTF_SOURCE_DIR and
# BTF_SHARED_DIR (read by the tests only). They hold inside this build; an installed btfkit has
# the installed include folder instead and passes no definitions on.
get_target_property(_btfkit_includes btfkit INTERFACE_INCLUDE_DIRECTORIES)
get_target_property(_btfkit_definitions btfkit INTERFACE_COMPILE_DEFINITIONS)
foreach(_property_values _btfkit_includes _btfkit_definitions)
  if(NOT ${_property_values})  # unset: <name>-NOTFOUND
    set(${_property_values})
  endif()
  set(_wrapped)
  foreach(_value IN LISTS ${_property_values})
    string(FIND "${_value}" "${PROJECT_SOURCE_DIR}" _in_source)
    string(FIND "${_value}" "${PROJECT_BINARY_DIR}" _in_build)
    if(_in_source GREATER -1 OR _in_build GREATER -1)
      set(_value "$<BUILD_INTERFACE:${_value}>")
    endif()
    list(APPEND _wrapped "${_value}")
  endforeach()
  set(${_property_values} "${_wrapped}")
endforeach()
list(APPEND _btfkit_includes "$<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>")
set_target_properties(
  btfkit PROPERTIES
  INTERFACE_INCLUDE_DIRECTORIES "${_btfkit_includes}"
  INTERFACE_COMPILE_DEFINITIONS "${_btfkit_definitions}"
  # A shared libbtfkit's ABI changes with every minor version while it is 0.x.
  VERSION ${PROJECT_VERSION} SOVERSION ${PROJECT_VERSION_MAJOR}.${PROJECT_VERSION_MINOR})
# The public headers are C++20 (std::span, designated initializers): consumers compile as such.
target_compile_features(btfkit PUBLIC cxx_std_20)

# ---- the dependencies a consumer must find -----------------------------------------------------
# One call per library that CMakeLists.txt links into btfkit (target_link_libraries(btfkit ...)):
#   ITEMS  the link items as written there
#   FIND   the arguments of find_dependency() in btfkitConfig.cmake, for imported targets that a
#          Find module or package config makes
#   PKG    prefix and module of pkg_check_modules(... IMPORTED_TARGET): its PkgConfig::<prefix>
#          target is not exported, so btfkitConfig.cmake makes it again
#   PC     the pkg-config module(s) for btfkit.pc, or LIBS: plain linker flags where there is none
# Items that are absolute library paths (HDF5's) are exported as they are and need no FIND.
# btfkitConfig.cmake finds what the exported target names (static: every item; shared: the
# PUBLIC ones); a link item without a line here is reported when configuring.
set(_btfkit_known_items)
macro(btfkit_dependency)
  cmake_parse_arguments(_dep "" "FIND;PKG;LIBS" "ITEMS;PC" ${ARGN})
  foreach(_item IN LISTS _dep_ITEMS)
    list(APPEND _btfkit_known_items "${_item}")
    set("_btfkit_find_${_item}" "${_dep_FIND}")
    set("_btfkit_pkg_${_item}" "${_dep_PKG}")
    set("_btfkit_pc_${_item}" "${_dep_PC}")
    set("_btfkit_libs_${_item}" "${_dep_LIBS}")
  endforeach()
endmacro()
btfkit_dependency(ITEMS Eigen3::Eigen FIND "Eigen3 3.3 NO_MODULE" PC eigen3)
btfkit_dependency(ITEMS fmt::fmt FIND fmt PC fmt)
btfkit_dependency(ITEMS nlohmann_json::nlohmann_json FIND nlohmann_json PC nlohmann_json)
btfkit_dependency(ITEMS TBB::tbb FIND TBB PC tbb)
btfkit_dependency(ITEMS JPEG::JPEG FIND JPEG PC libjpeg)
btfkit_dependency(ITEMS PkgConfig::LIBZIP PKG "LIBZIP libzip" PC libzip)
btfkit_dependency(ITEMS Qhull::qhull_r FIND Qhull PC qhull_r)
btfkit_dependency(ITEMS ${HDF5_C_LIBRARIES} PC hdf5)
btfkit_dependency(ITEMS PkgConfig::XXHASH PKG "XXHASH libxxhash" PC libxxhash)
btfkit_dependency(ITEMS PkgConfig::ZSTD PKG "ZSTD libzstd" PC libzstd)
btfkit_dependency(ITEMS PkgConfig::DEFLATE PKG "DEFLATE libdeflate" PC libdeflate)
btfkit_dependency(ITEMS PkgConfig::KISSFFT PKG "KISSFFT kissfft-float" PC kissfft-float)
btfkit_dependency(ITEMS PkgConfig::OPENBLAS PKG "OPENBLAS openblas" PC openblas)
btfkit_dependency(ITEMS embree FIND "embree 3" LIBS -lembree3)
btfkit_dependency(ITEMS tinyobjloader::tinyobjloader FIND tinyobjloader PC tinyobjloader)
btfkit_dependency(ITEMS Boost::headers FIND "Boost 1.74")  # header-only: nothing to link
btfkit_dependency(ITEMS Threads::Threads FIND Threads LIBS -pthread)

# Public items: those the exported target names for every use; a static library names the
# PRIVATE ones too, as $<LINK_ONLY:...> (needed when linking only).
get_target_property(_btfkit_links btfkit LINK_LIBRARIES)
get_target_property(_btfkit_interface_links btfkit INTERFACE_LINK_LIBRARIES)
set(_btfkit_public_links)
set(_btfkit_exported_links)
foreach(_item IN LISTS _btfkit_interface_links)
  if(_item MATCHES "^\\$<LINK_ONLY:(.*)>$")
    list(APPEND _btfkit_exported_links "${CMAKE_MATCH_1}")
  else()
    list(APPEND _btfkit_public_links "${_item}")
    list(APPEND _btfkit_exported_links "${_item}")
  endif()
endforeach()

set(BTFKIT_CONFIG_DEPENDENCIES)  # lines of btfkitConfig.cmake
set(_btfkit_pc_public)           # pkg-config modules and flags, public and private
set(_btfkit_pc_private)
set(_btfkit_libs_public)
set(_btfkit_libs_private)
foreach(_item IN LISTS _btfkit_links)
  if(NOT _item IN_LIST _btfkit_known_items)
    message(WARNING "cmake/install.cmake: btfkit links '${_item}', which the installed package "
                    "does not know how to find: add a btfkit_dependency() line for it")
    continue()
  endif()
  if(_item IN_LIST _btfkit_exported_links)
    if(_btfkit_find_${_item})
      list(APPEND BTFKIT_CONFIG_DEPENDENCIES "find_dependency(${_btfkit_find_${_item}})")
    elseif(_btfkit_pkg_${_item})
      list(APPEND BTFKIT_CONFIG_DEPENDENCIES "_btfkit_pkg_check_modules(${_btfkit_pkg_${_item}})")
    endif()
  endif()
  # btfkit.pc: a static libbtfkit.a is useless without its dependencies, so they are all public
  # there (plain `pkg-config --libs btfkit` links); a shared one keeps its own private.
  if(_item IN_LIST _btfkit_public_links OR NOT BTFKIT_SHARED)
    list(APPEND _btfkit_pc_public ${_btfkit_pc_${_item}})
    list(APPEND _btfkit_libs_public ${_btfkit_libs_${_item}})
  else()
    list(APPEND _btfkit_pc_private ${_btfkit_pc_${_item}})
    list(APPEND _btfkit_libs_private ${_btfkit_libs_${_item}})
  endif()
endforeach()
foreach(_list BTFKIT_CONFIG_DEPENDENCIES _btfkit_pc_public _btfkit_pc_private _btfkit_libs_public
              _btfkit_libs_private)
  list(REMOVE_DUPLICATES ${_list})
endforeach()
list(JOIN BTFKIT_CONFIG_DEPENDENCIES "\n" BTFKIT_CONFIG_DEPENDENCIES)

# ---- library, command, image module --------------------------------------------------------------
install(TARGETS btfkit EXPORT btfkitTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT devel
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT runtime NAMELINK_COMPONENT devel
        RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT runtime)
# Where core/image.cpp looks for the installed module (btf/core/image_module_paths.h).
install(TARGETS btfkit_images LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}/btfkit COMPONENT runtime)
install(TARGETS btf RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT runtime)
# The installed command finds a shared libbtfkit in the prefix's lib folder, wherever it is.
if(BTFKIT_SHARED)
  file(RELATIVE_PATH _btfkit_bin_to_lib /prefix/${CMAKE_INSTALL_BINDIR}
       /prefix/${CMAKE_INSTALL_LIBDIR})
  set_target_properties(btf PROPERTIES INSTALL_RPATH "$ORIGIN/${_btfkit_bin_to_lib}")
endif()

# ---- the web viewer (`btf serve` and `btf bundle` find it beside the command) and btf(1) ---------
# The source maps stay out: they hold the bundled npm packages' sources, for debugging a build.
if(BTF_WEB_BUILT)
  install(DIRECTORY ${CMAKE_BINARY_DIR}/web/ DESTINATION ${CMAKE_INSTALL_DATADIR}/btfkit/web
          COMPONENT runtime PATTERN "*.map" EXCLUDE)
endif()
install(FILES ${BTF_MAN_PAGE} DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT runtime)

# ---- public headers: the include closure of btf/btf.h --------------------------------------------
# The compiler lists what btf/btf.h includes (-MM) into a depfile, which also tells Ninja to list
# again when any of those headers changes; the install script installs the ones under src/.
set(BTFKIT_HEADER_LIST ${CMAKE_BINARY_DIR}/btfkit_public_headers.d)
add_custom_command(
  OUTPUT ${BTFKIT_HEADER_LIST}
  COMMAND ${CMAKE_CXX_COMPILER} -std=c++20 -MM -MT ${BTFKIT_HEADER_LIST} -MF ${BTFKIT_HEADER_LIST}
          "-I$<JOIN:$<REMOVE_DUPLICATES:$<TARGET_PROPERTY:btfkit,INCLUDE_DIRECTORIES>>,;-I>"
          ${PROJECT_SOURCE_DIR}/src/btf/btf.h
  DEPENDS ${PROJECT_SOURCE_DIR}/src/btf/btf.h
  DEPFILE ${BTFKIT_HEADER_LIST}
  COMMAND_EXPAND_LISTS VERBATIM
  COMMENT "Listing the public headers (the include closure of btf/btf.h)")
add_custom_target(btfkit_public_headers ALL DEPENDS ${BTFKIT_HEADER_LIST})
install(CODE "set(BTFKIT_HEADER_LIST \"${BTFKIT_HEADER_LIST}\")
set(BTFKIT_HEADER_ROOT \"${PROJECT_SOURCE_DIR}/src\")
set(BTFKIT_HEADER_DESTINATION \"${CMAKE_INSTALL_INCLUDEDIR}\")" COMPONENT devel)
install(SCRIPT ${CMAKE_CURRENT_LIST_DIR}/install_headers.cmake COMPONENT devel)

# ---- the CMake package: find_package(btfkit CONFIG) --------------------------------------------
install(EXPORT btfkitTargets NAMESPACE btfkit:: DESTINATION ${BTFKIT_INSTALL_CMAKEDIR}
        COMPONENT devel)
configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/btfkitConfig.cmake.in
                              ${CMAKE_BINARY_DIR}/cmake/btfkitConfig.cmake
                              INSTALL_DESTINATION ${BTFKIT_INSTALL_CMAKEDIR})
# 0.x: a minor version may break the API.
write_basic_package_version_file(${CMAKE_BINARY_DIR}/cmake/btfkitConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/cmake/btfkitConfig.cmake
              ${CMAKE_BINARY_DIR}/cmake/btfkitConfigVersion.cmake
        DESTINATION ${BTFKIT_INSTALL_CMAKEDIR} COMPONENT devel)

# ---- pkg-config: btfkit.pc -----------------------------------------------------------------------
# Relocatable: the prefix is found from where the .pc file lies (${pcfiledir}).
file(RELATIVE_PATH BTFKIT_PC_PREFIX /prefix/${CMAKE_INSTALL_LIBDIR}/pkgconfig /prefix)
string(REGEX REPLACE "/$" "" BTFKIT_PC_PREFIX "\${pcfiledir}/${BTFKIT_PC_PREFIX}")
list(JOIN _btfkit_pc_public " " BTFKIT_PC_REQUIRES)
list(JOIN _btfkit_pc_private " " BTFKIT_PC_REQUIRES_PRIVATE)
list(JOIN _btfkit_libs_public " " BTFKIT_PC_LIBS)
list(JOIN _btfkit_libs_private " " BTFKIT_PC_LIBS_PRIVATE)
configure_file(${CMAKE_CURRENT_LIST_DIR}/btfkit.pc.in ${CMAKE_BINARY_DIR}/cmake/btfkit.pc @ONLY)
install(FILES ${CMAKE_BINARY_DIR}/cmake/btfkit.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig
        COMPONENT devel)

# ---- the Python module: cmake --install build/release --component python --prefix /usr/local -----
# Into the site folder of the Python the module was built for, relative to the prefix: the
# interpreter's platlib layout with its own folder name (Debian's python3:
# lib/python3.11/dist-packages, searched under /usr/local and /usr alike).
if(TARGET btfkit_python)
  execute_process(
    COMMAND ${Python3_EXECUTABLE} -c
            "import os, sysconfig
base = sysconfig.get_path('platlib', 'posix_prefix', vars={'base': '/', 'platbase': '/'})
print(os.path.join(os.path.relpath(os.path.dirname(base), '/'),
                   os.path.basename(sysconfig.get_path('platlib'))), end='')"
    OUTPUT_VARIABLE _btfkit_python_dir RESULT_VARIABLE _btfkit_python_result)
  if(NOT _btfkit_python_result EQUAL 0 OR NOT _btfkit_python_dir)
    message(FATAL_ERROR "cmake/install.cmake: ${Python3_EXECUTABLE} did not say where its "
                        "packages go (set BTFKIT_INSTALL_PYTHONDIR)")
  endif()
  set(BTFKIT_INSTALL_PYTHONDIR ${_btfkit_python_dir} CACHE STRING
      "Where `--component python` installs the btfkit package, relative to the prefix")
  install(TARGETS btfkit_python LIBRARY DESTINATION ${BTFKIT_INSTALL_PYTHONDIR}/btfkit
          COMPONENT python EXCLUDE_FROM_ALL)
  install(FILES ${BTF_PYTHON_SOURCES} DESTINATION ${BTFKIT_INSTALL_PYTHONDIR}/btfkit
          COMPONENT python EXCLUDE_FROM_ALL)
  install(TARGETS btfkit_images LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}/btfkit
          COMPONENT python EXCLUDE_FROM_ALL)
  # The module tells the library where the image module lies relative to itself
  # (btf::add_image_module_candidate), so an installed module reads pictures from any prefix.
  file(RELATIVE_PATH _btfkit_python_to_images /prefix/${BTFKIT_INSTALL_PYTHONDIR}/btfkit
       /prefix/${CMAKE_INSTALL_LIBDIR}/btfkit)
  target_compile_definitions(btfkit_python PRIVATE
                             BTFKIT_PYTHON_TO_IMAGES="${_btfkit_python_to_images}")
  if(BTFKIT_SHARED)
    install(TARGETS btfkit LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} NAMELINK_SKIP
            COMPONENT python EXCLUDE_FROM_ALL)
    file(RELATIVE_PATH _btfkit_python_to_lib /prefix/${BTFKIT_INSTALL_PYTHONDIR}/btfkit
         /prefix/${CMAKE_INSTALL_LIBDIR})
    set_target_properties(btfkit_python PROPERTIES
                          INSTALL_RPATH "$ORIGIN/${_btfkit_python_to_lib}")
  endif()
endif()

# ---- tests --------------------------------------------------------------------------------------
if(BTF_BUILD_TESTS)
  set(_btfkit_install_test_env
      "CMAKE=${CMAKE_COMMAND}" "CXX=${CMAKE_CXX_COMPILER}" "NINJA=${CMAKE_MAKE_PROGRAM}"
      "PKG_CONFIG=${PKG_CONFIG_EXECUTABLE}" "LIBDIR=${CMAKE_INSTALL_LIBDIR}"
      "INCLUDEDIR=${CMAKE_INSTALL_INCLUDEDIR}" "BINDIR=${CMAKE_INSTALL_BINDIR}")
  add_test(NAME Install.consumer
           COMMAND bash ${PROJECT_SOURCE_DIR}/tests/install_consumer.sh consumer
                   ${CMAKE_BINARY_DIR} ${PROJECT_SOURCE_DIR})
  set_tests_properties(Install.consumer PROPERTIES ENVIRONMENT "${_btfkit_install_test_env}"
                                                   TIMEOUT 300 COST 300)
  if(TARGET btfkit_python)
    add_test(NAME Install.python
             COMMAND bash ${PROJECT_SOURCE_DIR}/tests/install_consumer.sh python
                     ${CMAKE_BINARY_DIR} ${PROJECT_SOURCE_DIR})
    list(APPEND _btfkit_install_test_env "PYTHON=${Python3_EXECUTABLE}"
         "PYTHON_DIR=${BTFKIT_INSTALL_PYTHONDIR}")
    set_tests_properties(Install.python PROPERTIES ENVIRONMENT "${_btfkit_install_test_env}"
                                                   TIMEOUT 300)
    # The Debian package `make package` builds (cmake/package.cmake) in build/package, checked
    # from this build's tests (`make test` makes it first).
    add_test(NAME Install.deb
             COMMAND bash ${PROJECT_SOURCE_DIR}/tests/install_consumer.sh deb ${CMAKE_BINARY_DIR}
                     ${PROJECT_SOURCE_DIR})
    set_tests_properties(Install.deb PROPERTIES
                         ENVIRONMENT "${_btfkit_install_test_env};DEB=${PROJECT_SOURCE_DIR}/build/package/btfkit_${PROJECT_VERSION}_amd64.deb;VERSION=${PROJECT_VERSION};RELEASE_BTF=$<TARGET_FILE:btf>"
                         TIMEOUT 600 COST 400)
  endif()
endif()
