// One process per output directory: the lock every command that writes into a run or output directory takes
// before it opens anything there for writing. Not the atomic writing of each file (atomic.hpp).
#pragma once
#include <string>

namespace hinf {

/// Creates DIR if needed and holds an exclusive flock(2) on DIR/.hinf.lock for the object's lifetime; the
/// kernel drops it when the process ends in any way (kill -9 included), so a lock is never stale. The file
/// holds the holder's pid and command line for the message. A second process gets one line naming DIR and
/// the holder. Under mpirun only the writing process (rank 0 of its group) locks. Within one process the lock nests:
/// a command holds DIR's for all it does there (training, the selection, the acceptance check, a second run swapped
/// in), and the training inside takes it again without being refused by its own process.
class RunDirLock {
public:
    RunDirLock(const std::string& dir, const std::string& command);
    ~RunDirLock();
    RunDirLock(const RunDirLock&) = delete;
    RunDirLock& operator=(const RunDirLock&) = delete;

private:
    int fd_ = -1;      // the flocked file; -1 where this process already held DIR's lock (nested) or not root
    std::string key_;  // DIR's canonical path in the process's table of held locks ("" where none was taken)
};

}  // namespace hinf
