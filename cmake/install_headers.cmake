# SPDX-License-Identifier: MIT
# Installs the public headers: the include closure of btf/btf.h, as the compiler listed it into
# the depfile BTFKIT_HEADER_LIST ("target: header header \ ..."). Run by `cmake --install`
# (install(SCRIPT) in cmake/install.cmake, which sets BTFKIT_HEADER_LIST, BTFKIT_HEADER_ROOT
# (src/) and BTFKIT_HEADER_DESTINATION). Headers outside BTFKIT_HEADER_ROOT are the dependencies'
# own and are not installed.

if(NOT EXISTS "${BTFKIT_HEADER_LIST}")
  message(FATAL_ERROR "${BTFKIT_HEADER_LIST} is missing: build btfkit (target "
                      "btfkit_public_headers) before installing it")
endif()
file(READ "${BTFKIT_HEADER_LIST}" list)
string(REPLACE "\\\n" " " list "${list}")
string(REGEX REPLACE "^[^:]*: " "" list "${list}")
separate_arguments(headers UNIX_COMMAND "${list}")

if(IS_ABSOLUTE "${BTFKIT_HEADER_DESTINATION}")
  set(destination "${BTFKIT_HEADER_DESTINATION}")
else()
  set(destination "${CMAKE_INSTALL_PREFIX}/${BTFKIT_HEADER_DESTINATION}")
endif()
set(count 0)
foreach(header IN LISTS headers)
  file(RELATIVE_PATH relative "${BTFKIT_HEADER_ROOT}" "${header}")
  if(relative MATCHES "^\\.\\./" OR IS_ABSOLUTE "${relative}")
    continue()
  endif()
  get_filename_component(folder "${relative}" DIRECTORY)
  file(INSTALL DESTINATION "${destination}/${folder}" TYPE FILE FILES "${header}")
  math(EXPR count "${count} + 1")
endforeach()
if(count EQUAL 0)
  message(FATAL_ERROR "${BTFKIT_HEADER_LIST} names no header under ${BTFKIT_HEADER_ROOT}")
endif()
