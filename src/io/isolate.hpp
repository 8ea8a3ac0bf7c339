// Running a reader of a user-supplied HDF5 file in a child process, so that a crash inside libhdf5
// on a damaged file becomes one error line instead of a segfault. Not the readers themselves.
#pragma once
#include <functional>
#include <string>

namespace hinf {

/// Runs fn() in a forked child (stderr to /dev/null; no OpenMP inside fn: the child of a process with
/// OpenMP threads must not start a team). Returns "" when fn returned, the hinf::Error text when it threw,
/// or a "the file is damaged: reading it crashed the HDF5 library (signal N)" line when the child died.
/// Without fork/pipe, runs fn() in-process.
std::string run_isolated(const std::function<void()>& fn);

}  // namespace hinf
