// Confined, atomic file writing: the one place that decides where a node or a
// tool may write a file and how.
//
// A service request (export_report) may name a subfolder of a configured
// root folder. ResolveSubfolder() accepts only a relative path of plain
// names (no "..", no ".", no absolute path, no control character such as a
// newline, each name <= 255 bytes), creates the missing folders one by one
// with mkdirat() below file descriptors opened with O_NOFOLLOW|O_DIRECTORY
// (so a symbolic link on the way is refused, never followed), and checks
// the result again after resolution (realpath) to lie inside the root.
//
// WriteFileAtomically() writes through a temporary created by mkstemp() in
// the target folder (O_CREAT|O_EXCL: a link planted at any name is never
// opened), fsyncs it and renames it over the final name, so a reader never
// sees a half-written file. Every refusal throws InvalidArgument, every
// failed write IoError, each naming the path and the reason.
#pragma once

#include <string>

namespace slope_monitor {
namespace io {

// Longest identifier (point id, target id, receiver id) the graph accepts and
// writes into file names: printable ASCII, 1..kMaxIdLength characters.
constexpr size_t kMaxIdLength = 64;

// Empty when `id` is a usable identifier, else why not ("is empty", "has
// 250 characters (at most 64)", "contains the control character 0x0a").
std::string IdProblem(const std::string& id);

// Checks one file or folder name: non-empty, no '/', not "." or "..", no
// control character, at most 255 bytes. Throws InvalidArgument naming `what`.
void CheckFileName(const std::string& name, const std::string& what);

// Creates `root` (mkdir -p; it is configuration, trusted, and may itself be
// reached through a link) and returns the real path of root/subfolder,
// created if absent, after the checks above. An empty subfolder is the root.
std::string ResolveSubfolder(const std::string& root, const std::string& subfolder);

// Writes `content` to `path` (its folder must exist) through an exclusive
// temporary in the same folder and a rename; the final name is replaced,
// never opened, so a link at it is replaced rather than followed.
void WriteFileAtomically(const std::string& path, const std::string& content);

// Fail early: creates `folder` (mkdir -p) and writes and removes a probe
// file in it (mkstemp), so a run finds an unwritable output folder before it
// works, not at its end. Throws IoError naming `what` (e.g. "--report-dir"),
// the folder and the reason.
void CheckFolderWritable(const std::string& folder, const std::string& what);

}  // namespace io
}  // namespace slope_monitor
