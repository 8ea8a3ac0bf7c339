# `cmake --install BUILD [--prefix P]`: the public headers (include/hinf/), the static libraries hinf and
# hinf_kernels, the `hinf` program and a CMake package, so that another project writes
#     find_package(hinf CONFIG REQUIRED)
#     target_link_libraries(app PRIVATE hinf::hinf)
# (docs/library.md; examples/consumer is such a project). The libraries are static: hinfConfig.cmake finds
# what they link (Eigen, OpenMP, HDF5, toml++, GiNaC, muParser, NLopt, SDPA, OpenBLAS, MPI) with
# find_dependency, as this file's top level found them.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)
set(HINF_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/hinf CACHE STRING "Where hinfConfig.cmake goes (under the prefix)")

install(TARGETS hinf hinf_kernels hinf_flags hinf_warnings EXPORT hinfTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS hinf-cli RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# only the public headers: the facade (hinf.hpp) and what it includes (error.hpp); config.hpp and h5.hpp
# are the library's own TOML/HDF5 helpers, installed with it because they live in include/hinf/
install(DIRECTORY ${CMAKE_CURRENT_SOURCE_DIR}/include/hinf DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
        FILES_MATCHING PATTERN "*.hpp")
install(EXPORT hinfTargets NAMESPACE hinf:: DESTINATION ${HINF_INSTALL_CMAKEDIR})

set(HINF_CONFIG_HAVE_MPI OFF)
if(HINF_MPI AND MPI_C_FOUND)
  set(HINF_CONFIG_HAVE_MPI ON)
endif()
configure_package_config_file(${CMAKE_CURRENT_SOURCE_DIR}/cmake/hinfConfig.cmake.in
                              ${CMAKE_CURRENT_BINARY_DIR}/hinfConfig.cmake INSTALL_DESTINATION ${HINF_INSTALL_CMAKEDIR})
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/hinfConfigVersion.cmake
                                 VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/hinfConfig.cmake ${CMAKE_CURRENT_BINARY_DIR}/hinfConfigVersion.cmake
              ${CMAKE_CURRENT_SOURCE_DIR}/cmake/FindSDPA.cmake
        DESTINATION ${HINF_INSTALL_CMAKEDIR})
