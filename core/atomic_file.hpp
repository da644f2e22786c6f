// Every file the program writes appears under its name only when it is complete: it is written to a
// temporary file beside it (same folder, so the rename is atomic on one file system) and renamed over the
// final name by commit(). An AtomicFile destroyed before commit() (an exception on the way, a failed
// check) removes its temporary, so a failed command leaves nothing half-written.
//
// The temporary is "<folder>/.<stem>.<pid>.tmp<extension>": hidden, unique per process (two processes
// writing the same result do not share it), and with the final extension kept, for writers that pick the
// format by extension (OpenImageIO).
#pragma once

#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

namespace hp {

class AtomicFile {
 public:
  /// Checks the path (check_output_path; `what` names the option or kind of file in its errors). Missing
  /// parent folders are an error when the file is written, unless `create_folders` (then they are made
  /// now). Nothing is written yet.
  explicit AtomicFile(std::filesystem::path path, const std::string& what = "", bool create_folders = false);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  const std::filesystem::path& path() const { return path_; }
  /// Where a writer that opens files itself (OpenImageIO, stdio) writes.
  const std::filesystem::path& temp_path() const { return temp_; }
  /// A binary stream on the temporary, opened on first use.
  std::ostream& stream();
  /// Closes the stream (if used) and renames the temporary over path(). InputError naming the path on a
  /// failed write or rename; the temporary is removed then too.
  void commit();

 private:
  std::filesystem::path path_, temp_;
  std::ofstream out_;
  bool committed_ = false;
};

/// Whether a temporary of an AtomicFile for `path` (of any process) lies beside it: what an interrupted or
/// failed write would leave behind. For tests and checks.
bool atomic_temporary_exists(const std::filesystem::path& path);

/// Writes `content` (text or bytes, written as they are) to `path` through an AtomicFile.
void write_file_atomically(const std::filesystem::path& path, std::string_view content, const std::string& what = "");

}  // namespace hp
