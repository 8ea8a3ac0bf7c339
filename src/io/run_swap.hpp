// Two runs' files exchanged between a run directory and another (DIR and DIR/alternative, eval/acceptance.cpp
// swap_runs), journalled so that a process killed at any moment of the exchange leaves nothing that the next lock of
// DIR (io/run_lock.hpp) does not put in its place.
#pragma once
#include <string>
#include <vector>

namespace hinf {

/// The folder inside DIR that holds DIR's entries during an exchange, and the journal it keeps there: a text file
/// of "phase P" (1: DIR's entries are moving into the folder, 2: ALT's into DIR, 3: the folder's into ALT), then
/// ALT's path, then one entry name a line. Written atomically (io/atomic.hpp) before each phase's first move.
inline constexpr const char* kSwapFolder = "alternative.swap";
inline constexpr const char* kSwapJournal = "journal";

/// Exchanges the entries `names` (files or folders; each may be missing on either side) between dir and alt by
/// renames through dir/kSwapFolder, phase by phase with the journal. An exchange a kill interrupted there is
/// finished first.
void swap_entries(const std::string& dir, const std::string& alt, const std::vector<std::string>& names);

/// Where dir holds an exchange a kill interrupted (dir/kSwapFolder), finishes it from its journal's phase (each
/// phase moves only what is still on its source side, so a phase half done is done again safely) and returns ALT's
/// path; a folder without a journal (killed before the first move) is removed and "" returned; "" where there is
/// none. A damaged journal throws one line naming the folder.
std::string finish_interrupted_swap(const std::string& dir);

}  // namespace hinf
