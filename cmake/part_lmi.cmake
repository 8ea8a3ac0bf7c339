# The LMI route of seed 002: SDPA behind src/lmi/sdp.hpp. Only src/lmi/sdp_sdpa.cpp includes SDPA's
# headers (they pull `using namespace std`, MUMPS and pthread); everything else sees our interface.
find_package(SDPA REQUIRED)
target_link_libraries(hinf PUBLIC SDPA::SDPA)

# GCC 12 + Eigen 3.4 with -march=native (AVX-512) report false -Wmaybe-uninitialized inside Eigen's packet
# math (Eigen issue 2506). Silenced for this part's sources only; the rest of the project decides for itself.
if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
  file(GLOB _hinf_lmi_sources ${CMAKE_CURRENT_SOURCE_DIR}/src/lmi/*.cpp ${CMAKE_CURRENT_SOURCE_DIR}/tests/lmi/*.cpp)
  set_source_files_properties(${_hinf_lmi_sources} PROPERTIES COMPILE_OPTIONS -Wno-maybe-uninitialized)
endif()
