// Names of the scratch files of the disk levels ("disk", "multilevel") and the removal of those a
// killed process left behind.
//
// A run removes its scratch files when it ends, fails or is interrupted (destructors); kill -9, a
// power loss or an out-of-memory kill leave them. Their names say whose they are:
//   PREFIX-PID-HOST-COUNTER[-TIME].EXT   (PREFIX hindsight or hindsight-multilevel, EXT .h5 or .slots)
// with HOST eight hex digits of the FNV-1a hash of the machine's host name. Before a process creates
// its first scratch file in a directory, it removes the scratch files there whose HOST is its own and
// whose PID names no running process: the process that wrote them is gone, and nothing else reads
// them (a run's files are never resumed; --resume restarts the trajectory from the last iteration).
// Files of other hosts (a directory shared by the ranks of several machines) and files in the older
// naming without HOST are never touched: their owner's liveness cannot be checked from here. A PID
// reused by an unrelated process keeps its file until that process ends (never a live file removed).
// Files a run keeps on purpose (keep=true) are named PREFIX-PID-kept-COUNTER-TIME.EXT and are
// never removed.
#pragma once

#include <string>

namespace hindsight::internal {

/// A new unique file name PREFIX-PID-HOST-COUNTER-TIME followed by `extension` (with its dot); HOST
/// is "kept" for a file the run keeps (never removed as stale).
std::string scratchFileName(const std::string& prefix, const std::string& extension, bool kept);

/// Removes the stale scratch files of dead processes of this host in `directory`, once per directory
/// and process (later calls return 0 at once). Returns how many were removed; never throws (a file
/// that cannot be removed stays, a directory that cannot be listed is skipped).
int removeStaleScratchFiles(const std::string& directory) noexcept;

/// The eight hex digits HOST of this machine's scratch file names.
std::string scratchHostTag();

/// True when `name` (without directory) is a scratch file name of this host whose process is gone.
bool isStaleScratchFile(const std::string& name);

}  // namespace hindsight::internal
