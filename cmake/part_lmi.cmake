# The LMI route of seed 002: SDPA behind src/lmi/sdp.hpp. Only src/lmi/sdp_sdpa.cpp includes SDPA's
# headers (they pull `using namespace std`, MUMPS and pthread); everything else sees our interface.
find_package(SDPA REQUIRED)
target_link_libraries(hinf PUBLIC SDPA::SDPA)

