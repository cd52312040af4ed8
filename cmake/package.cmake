# SPDX-License-Identifier: MIT
# The Debian package: `make package` configures the `package` preset (portable x86-64 code,
# installed under /usr, Debian's hardening flags) and runs CPack, which writes
# build/package/btfkit_<version>_amd64.deb holding every install component below:
#
#   runtime  the btf command, its image module, the web viewer (share/btfkit/web), btf(1)
#   devel    libbtfkit, its public headers, the CMake package and btfkit.pc
#   python   the Python module, for Debian's python3 (lib/python3/dist-packages)
#   debian   /usr/share/doc/btfkit: copyright (DEP-5, from LICENSE), changelog.gz (Debian's
#            changelog form of CHANGELOG.md's packaged releases), CHANGELOG.md, README.md
#
# Depends: the shared libraries' packages, as dpkg-shlibdeps computes them, and python3 for the
# module. CTest's Install.deb (tests/install_consumer.sh deb) checks the package: its fields and
# files, lintian, and btf, the Python module and a find_package(btfkit) consumer run from it.

# ---- /usr/share/doc/btfkit ------------------------------------------------------------------------
set(BTFKIT_PACKAGE_MAINTAINER "btfkit developers <btfkit@packages.invalid>" CACHE STRING
    "The Debian package's Maintainer field and changelog signature: a distributor sets their own")
set(_btfkit_doc_dir ${CMAKE_INSTALL_DATADIR}/doc/btfkit)
set(_btfkit_debian_dir ${CMAKE_BINARY_DIR}/debian)
# copyright: the machine-readable form (DEP-5) around LICENSE's text.
file(READ ${PROJECT_SOURCE_DIR}/LICENSE _btfkit_license)
string(REGEX REPLACE "^MIT License\n\nCopyright \\(c\\) ([^\n]*)\n\n" "" _btfkit_license_body
                     "${_btfkit_license}")
set(_btfkit_copyright_holder "${CMAKE_MATCH_1}")
if(NOT _btfkit_copyright_holder)
  message(FATAL_ERROR "cmake/package.cmake: LICENSE does not start with the MIT licence's "
                      "title and copyright line")
endif()
string(STRIP "${_btfkit_license_body}" _btfkit_license_body)
string(REGEX REPLACE "\n\n" "\n.\n" _btfkit_license_body "${_btfkit_license_body}")
string(REGEX REPLACE "\n" "\n " _btfkit_license_body "${_btfkit_license_body}")
file(WRITE ${_btfkit_debian_dir}/copyright
"Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/
Upstream-Name: btfkit
Comment: The licences of the libraries btfkit's binaries link are in docs/licences.md of the
 source and in their own packages' copyright files.

Files: *
Copyright: ${_btfkit_copyright_holder}
License: MIT
 ${_btfkit_license_body}
")
# changelog.gz: CHANGELOG.md in Debian's changelog form (a native package's changelog), from the
# first release made as a Debian package (0.2.0); CHANGELOG.md itself holds the whole history.
if(Python3_EXECUTABLE)
  add_custom_command(
    OUTPUT ${_btfkit_debian_dir}/changelog.gz
    COMMAND ${Python3_EXECUTABLE} ${PROJECT_SOURCE_DIR}/scripts/debian_changelog.py
            ${PROJECT_SOURCE_DIR}/CHANGELOG.md "${BTFKIT_PACKAGE_MAINTAINER}"
            ${_btfkit_debian_dir}/changelog.gz
    DEPENDS ${PROJECT_SOURCE_DIR}/CHANGELOG.md ${PROJECT_SOURCE_DIR}/scripts/debian_changelog.py
    COMMENT "Writing the Debian changelog from CHANGELOG.md" VERBATIM)
  add_custom_target(debian_changelog ALL DEPENDS ${_btfkit_debian_dir}/changelog.gz)
  install(FILES ${_btfkit_debian_dir}/changelog.gz DESTINATION ${_btfkit_doc_dir}
          COMPONENT debian EXCLUDE_FROM_ALL)
endif()
install(FILES ${_btfkit_debian_dir}/copyright ${PROJECT_SOURCE_DIR}/README.md
              ${PROJECT_SOURCE_DIR}/CHANGELOG.md DESTINATION ${_btfkit_doc_dir} COMPONENT debian EXCLUDE_FROM_ALL)

# ---- CPack --------------------------------------------------------------------------------------
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME btfkit)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_VENDOR "the btfkit authors")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
set(CPACK_OUTPUT_FILE_PREFIX ${CMAKE_BINARY_DIR})
# Every component, in one package.
set(CPACK_COMPONENTS_ALL runtime devel debian)
if(TARGET btfkit_python)
  list(APPEND CPACK_COMPONENTS_ALL python)
endif()
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_GROUPING ALL_COMPONENTS_IN_ONE)
set(CPACK_DEBIAN_PACKAGE_NAME btfkit)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # btfkit_<version>_amd64.deb
set(CPACK_DEBIAN_PACKAGE_MAINTAINER "${BTFKIT_PACKAGE_MAINTAINER}")
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# The Python module is built for one Python minor version (its file name says which), and hands
# out NumPy arrays.
if(TARGET btfkit_python)
  set(_btfkit_python ${Python3_VERSION_MAJOR}.${Python3_VERSION_MINOR})
  math(EXPR _btfkit_python_next "${Python3_VERSION_MINOR} + 1")
  set(CPACK_DEBIAN_PACKAGE_DEPENDS
      "python3 (>= ${_btfkit_python}), python3 (<< ${Python3_VERSION_MAJOR}.${_btfkit_python_next}), python3-numpy")
endif()
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "openmpi-bin")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "measured material appearance (Bidirectional Texture Functions)")
# The extended description (CPack puts the summary above it).
set(CPACK_DEBIAN_PACKAGE_DESCRIPTION
"btfkit reads measured Bidirectional Texture Functions (Bonn UBO2003 and
UBO2014, UTIA, its own HDF5 form), synthesizes materials, compresses them
with several codecs (FMF, PCA over views, local PCA, MLVQ, perceptual
factorization), measures their fidelity, evaluates and samples them,
renders them in a path tracer and streams them to a WebGL2 viewer.
.
This package holds the btf command (btf(1); mpirun btf compress runs
across MPI ranks), the web viewer that btf serve serves, the C++ library
with its CMake package and pkg-config file, and the Python module (import
btfkit). Building against the library needs the -dev packages of the
libraries it links.")
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
include(CPack)
