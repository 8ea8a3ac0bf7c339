# FindSDPA: the SDPA semidefinite-programming solver's C++ callable library (Debian: libsdpa-dev).
# SDPA ships no CMake config; its link line (/usr/share/sdpa/make.inc) is libsdpa.a + sequential
# MUMPS (dmumps, mumps_common, mpiseq, pord, scotch, esmumps) + LAPACK/BLAS + gfortran + pthread.
# Defines the imported target SDPA::SDPA and SDPA_FOUND. Not a general MUMPS finder.

find_path(SDPA_INCLUDE_DIR sdpa_call.h)
find_library(SDPA_LIBRARY NAMES libsdpa.a sdpa PATHS /usr/lib /usr/lib/x86_64-linux-gnu)
find_path(SDPA_MUMPS_INCLUDE_DIR dmumps_c.h PATH_SUFFIXES mumps-seq-shared mumps_seq)

set(_sdpa_parts dmumps_seq mumps_common_seq mpiseq_seq pord_seq esmumps scotch scotcherr lapack blas gfortran quadmath)
set(_sdpa_libs "")
set(_sdpa_missing "")
foreach(_p ${_sdpa_parts})
  find_library(SDPA_DEP_${_p} NAMES ${_p} lib${_p}.so.5 PATHS /usr/lib/x86_64-linux-gnu /usr/lib/gcc/x86_64-linux-gnu/12)
  if(SDPA_DEP_${_p})
    list(APPEND _sdpa_libs ${SDPA_DEP_${_p}})
  elseif(NOT _p STREQUAL "scotcherr")
    list(APPEND _sdpa_missing ${_p})
  endif()
endforeach()
find_package(Threads REQUIRED)

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(SDPA
  REQUIRED_VARS SDPA_LIBRARY SDPA_INCLUDE_DIR
  REASON_FAILURE_MESSAGE "install libsdpa-dev libmumps-seq-dev libopenblas-dev (scripts/setup)")

if(SDPA_FOUND AND NOT TARGET SDPA::SDPA)
  if(_sdpa_missing)
    message(FATAL_ERROR "SDPA found but its dependencies are missing: ${_sdpa_missing} (install libmumps-seq-dev libopenblas-dev gfortran)")
  endif()
  add_library(SDPA::SDPA STATIC IMPORTED)
  set_target_properties(SDPA::SDPA PROPERTIES
    IMPORTED_LOCATION "${SDPA_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${SDPA_INCLUDE_DIR}"
    INTERFACE_LINK_LIBRARIES "${_sdpa_libs};Threads::Threads;m")
  if(SDPA_MUMPS_INCLUDE_DIR)
    set_property(TARGET SDPA::SDPA APPEND PROPERTY INTERFACE_INCLUDE_DIRECTORIES "${SDPA_MUMPS_INCLUDE_DIR}")
  endif()
endif()
mark_as_advanced(SDPA_INCLUDE_DIR SDPA_LIBRARY SDPA_MUMPS_INCLUDE_DIR)
