# Optional: the side-by-side benchmark against LibTorch (issue 8), built only when Debian's libtorch-dev
# is installed (scripts/bench-libtorch installs it). The library and the CLI never depend on it.
option(HINF_WITH_LIBTORCH "Build hinf-bench-libtorch when LibTorch is installed" ON)
if(HINF_WITH_LIBTORCH AND NOT HINF_SANITIZE)
  find_package(Torch QUIET)
endif()
if(Torch_FOUND AND HINF_WITH_LIBTORCH AND NOT HINF_SANITIZE)
  add_executable(hinf-bench-libtorch ${CMAKE_CURRENT_SOURCE_DIR}/bench/libtorch_step.cpp)
  target_link_libraries(hinf-bench-libtorch PRIVATE hinf ${TORCH_LIBRARIES} ${HINF_OPENBLAS_LIBRARY} hinf_warnings)
  message(STATUS "hinf: LibTorch ${Torch_VERSION} found, building hinf-bench-libtorch")
endif()
