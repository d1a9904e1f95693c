#pragma once
// Atomic output files (docs/design.md §6 "Atomicity"): every file marglab writes — results and
// track files (HDF5), text tracks, TUM trajectories, CSV, tables, captured windows, figures —
// appears at its path complete or not at all.
//
//   AtomicFile f(path);   creates the temporary sibling "<path>.tmp-<pid>-<n>" (same folder, so
//                         that rename(2) cannot cross file systems) and registers it
//   f.write(bytes);       write(2) until done; a short write (disk full, file size limit) throws
//   f.commit();           fsync, close, rename onto path (atomic on POSIX), fsync the folder
//   ~AtomicFile()         without commit(): closes and removes the temporary
//
// On any failure the previous file at path is untouched, the temporary is removed, and the
// InputError names the path, the temporary and the reason (strerror: "No space left on device").
// A path that exists but is not a regular file (a device node such as /dev/null, a FIFO, a
// socket) is refused, at construction and again just before the rename: renaming onto it would
// replace the node with a regular file (for /dev/null, breaking it for everyone).
//
// Live temporaries are listed in a fixed-size, lock-free registry so that a SIGINT/SIGTERM
// handler (interrupt.h) can unlink them with async-signal-safe calls only.

#include <cstddef>
#include <string>
#include <string_view>

namespace marglab {

class AtomicFile {
 public:
  // Throws InputError(path, 0, ...) when the temporary cannot be created.
  explicit AtomicFile(std::string path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  void write(const void* data, std::size_t size);
  void write(std::string_view bytes) { write(bytes.data(), bytes.size()); }
  // The temporary's descriptor, e.g. for gzdopen(dup(fd())); valid until commit().
  int fd() const { return fd_; }
  void commit();

  const std::string& path() const { return path_; }
  const std::string& temporaryPath() const { return tmp_path_; }

 private:
  [[noreturn]] void fail(const std::string& what, int error);
  void discard() noexcept;

  std::string path_;
  std::string tmp_path_;
  int fd_ = -1;
  int slot_ = -1;  // registry slot, -1 when not registered
};

// Throws InputError(path, 0, ...) when path exists (following symbolic links) and is not a regular
// file or a folder: "is a character device, not a regular file ...". Folders are left to the
// caller (a rename onto one fails, and a folder output is a folder).
void refuseSpecialFileOutput(const std::string& path);

// An output folder made ready before any work (`plot`, `report`, `notebooks`, `tables` fill one):
// created with its parents when missing; throws UsageError for "" and InputError naming the path
// and the reason when it cannot be created, is not a folder or is not writable.
void prepareOutputFolder(const std::string& path, const std::string& option);

// The whole text through an AtomicFile; creates missing parent folders first.
void writeFileAtomically(const std::string& path, std::string_view bytes);

namespace detail {
// Async-signal-safe: unlinks every registered temporary (for the interrupt handler).
void unlinkLiveTemporaries() noexcept;
// Number of registered temporaries (for tests).
int liveTemporaryCount();
}  // namespace detail

}  // namespace marglab
