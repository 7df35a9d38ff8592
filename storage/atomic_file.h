// The one atomic file write: a file that readers (and a restart after a crash) see either as it was
// (or absent) or complete, never torn.
//
// The contents go to a temporary file in the target's directory (the same file system, so the rename
// is atomic on POSIX), named PATH.tmp-PID-N; it is fsynced, renamed onto PATH, and the directory is
// fsynced so that the rename itself survives a power loss. On any failure the temporary file is removed
// and PATH is untouched. A process killed in between leaves its temporary file behind;
// removeStaleTemporaries() clears those of dead processes.
#pragma once

#include <cstdio>
#include <functional>
#include <string>

namespace hindsight {

/// `write` creates and fills the file at the temporary path it is given (for libraries that open
/// files by name, such as HDF5) and throws on failure; its exception reaches the caller unchanged.
/// Failures of the steps around it throw StorageError naming `path` and the system's reason.
void writeFileAtomically(const std::string& path, const std::function<void(const std::string&)>& write);

/// The same for a writer on an open stdio stream: `write` fills the stream and returns an empty
/// string on success, else the reason, which is thrown as StorageError naming `path`.
void writeStreamAtomically(const std::string& path, const std::function<std::string(std::FILE*)>& write);

/// `size` bytes at `data` as the whole file: a failed write throws StorageError "cannot write WHAT:
/// reason" naming `path` (WHAT e.g. "the SVG file").
void writeBytesAtomically(const std::string& path, const void* data, std::size_t size,
                          const std::string& what);

/// Removes the temporary files of `path` left by processes that no longer run (killed during a
/// write); those of running processes stay. Never throws.
void removeStaleTemporaries(const std::string& path);

/// The same for every target in `directory`: removes each NAME.tmp-PID-N there whose process no
/// longer runs (a results file, a picture, ...). Never throws.
void removeStaleTemporariesIn(const std::string& directory);

}  // namespace hindsight
