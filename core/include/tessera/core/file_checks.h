// Checks on the files a tool reads and writes, shared by the readers and the tools: open only
// regular files (a FIFO, socket or device would block or never end), and never write over an
// input (by any path to the same file).
#pragma once

#include <filesystem>
#include <optional>
#include <span>
#include <string>

namespace tessera {

/// Opens `path` read-only (O_CLOEXEC) without blocking on a FIFO, and keeps it only when it is
/// a regular file. Returns the descriptor (blocking mode, the caller closes it), or -1 with
/// `why` set: the errno text ("No such file or directory") or "not a regular file (a FIFO)".
int openRegularFile(const std::filesystem::path& path, std::string& why);

/// nullopt when `path` is a regular file (after symlinks); else why not, as openRegularFile.
/// For readers that open by name (std::ifstream, fopen): call it first so they never block.
std::optional<std::string> notRegularFile(const std::filesystem::path& path);

/// The entry of `inputs` that `output` is by any path (symlinks, "./", hard links: the same
/// device and inode), if any. Paths that do not exist match nothing.
std::optional<std::filesystem::path> sameFileAs(const std::filesystem::path& output,
                                                std::span<const std::filesystem::path> inputs);

/// Why `path` could not be opened for writing, given the errno of the failure: "the folder F
/// does not exist", "F is not a folder", "it is a folder", else the errno text.
std::string whyNotWritable(const std::filesystem::path& path, int error);

/// Why a file could not be written at `path` later (its folder missing or not writable, the
/// path a folder, or an existing file not writable), or nullopt; creates nothing. For outputs
/// written at the end of a run, refused at its start instead.
std::optional<std::string> notWritable(const std::filesystem::path& path);

}  // namespace tessera
