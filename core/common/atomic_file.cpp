#include "core/common/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <utility>

#include "core/common/error.h"
#include "core/common/interrupt.h"

namespace marglab {
namespace {

// Registry of live temporaries: a slot is free (0), being filled (1) or live (2). The handler
// reads only live slots, whose path is complete and unchanging until the slot is freed.
constexpr int kSlots = 64;
constexpr std::size_t kPathBytes = 4096;
struct Slot {
  std::atomic<int> state{0};
  char path[kPathBytes] = {};
};
std::array<Slot, kSlots> g_slots;
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler reads the registry");

// A temporary without a slot (more than kSlots at once, or a very long path) is still removed by
// its owner; only an interrupt could then leave it behind.
int registerTemporary(const std::string& path) {
  if (path.size() >= kPathBytes) return -1;
  for (int i = 0; i < kSlots; ++i) {
    int expected = 0;
    if (g_slots[i].state.compare_exchange_strong(expected, 1)) {
      std::memcpy(g_slots[i].path, path.c_str(), path.size() + 1);
      g_slots[i].state.store(2);
      return i;
    }
  }
  return -1;
}

void unregisterTemporary(int slot) {
  if (slot >= 0) g_slots[slot].state.store(0);
}

// The folder's entry of the renamed file reaches the disk too; a file system that cannot sync a
// folder (EINVAL) still renamed atomically.
void syncFolder(const std::string& path) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  const int fd = ::open(parent.empty() ? "." : parent.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

const char* specialFileKind(mode_t mode) {
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISFIFO(mode)) return "a FIFO (named pipe)";
  if (S_ISSOCK(mode)) return "a socket";
  return nullptr;
}

}  // namespace

void refuseSpecialFileOutput(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return;
  const char* kind = specialFileKind(st.st_mode);
  if (kind == nullptr) return;
  throw InputError(path, 0,
                   std::string("is ") + kind +
                       ", not a regular file: marglab writes an output to a temporary file and "
                       "renames it onto the path, which would replace it; give the path of a "
                       "regular file (to discard an output, write it into a temporary folder)");
}

namespace detail {
void unlinkLiveTemporaries() noexcept {
  for (Slot& slot : g_slots) {
    if (slot.state.load() == 2) ::unlink(slot.path);
  }
}

int liveTemporaryCount() {
  int n = 0;
  for (const Slot& slot : g_slots) n += slot.state.load() == 2 ? 1 : 0;
  return n;
}
}  // namespace detail

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)) {
  static std::atomic<int> counter{0};
  installInterruptCleanup();
  refuseSpecialFileOutput(path_);
  tmp_path_ = path_ + ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(counter++);
  slot_ = registerTemporary(tmp_path_);
  fd_ = ::open(tmp_path_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    const int error = errno;
    unregisterTemporary(slot_);
    slot_ = -1;
    throw InputError(path_, 0, "cannot create " + tmp_path_ + ": " + std::strerror(error));
  }
}

AtomicFile::~AtomicFile() { discard(); }

void AtomicFile::discard() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  if (!tmp_path_.empty()) ::unlink(tmp_path_.c_str());
  unregisterTemporary(slot_);
  slot_ = -1;
}

void AtomicFile::fail(const std::string& what, int error) {
  const std::string message = what + " " + tmp_path_ + ": " + std::strerror(error);
  discard();
  throw InputError(path_, 0, message);
}

void AtomicFile::write(const void* data, std::size_t size) {
  if (fd_ < 0) throw InputError(path_, 0, "write after commit");
  const char* p = static_cast<const char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd_, p, size);
    if (n < 0 && errno == EINTR) continue;
    // write(2) returns a short count before it fails: the next call reports why.
    if (n < 0) fail("cannot write", errno);
    if (n == 0) fail("cannot write", EIO);
    p += n;
    size -= static_cast<std::size_t>(n);
  }
}

void AtomicFile::commit() {
  if (fd_ < 0) throw InputError(path_, 0, "commit: the file is not being written");
  if (::fsync(fd_) != 0) fail("cannot sync", errno);
  const int fd = std::exchange(fd_, -1);
  if (::close(fd) != 0) fail("cannot close", errno);
  try {
    refuseSpecialFileOutput(path_);  // created while the temporary was written
  } catch (const InputError&) {
    discard();
    throw;
  }
  if (std::rename(tmp_path_.c_str(), path_.c_str()) != 0) {
    const int error = errno;
    const std::string message = "cannot rename " + tmp_path_ + " onto it: " + std::strerror(error);
    discard();
    throw InputError(path_, 0, message);
  }
  unregisterTemporary(slot_);
  slot_ = -1;
  tmp_path_.clear();
  syncFolder(path_);
}

void prepareOutputFolder(const std::string& path, const std::string& option) {
  namespace fs = std::filesystem;
  if (path.empty()) throw UsageError(option + " is empty: expected the path of a folder to write");
  std::error_code ec;
  fs::create_directories(path, ec);
  if (ec) throw InputError(path, 0, "cannot create the folder of " + option + ": " + ec.message());
  if (!fs::is_directory(path, ec)) {
    throw InputError(path, 0, "is not a folder: expected a folder to write (" + option + ")");
  }
  if (::access(path.c_str(), W_OK) != 0) {
    throw InputError(path, 0, "not writable: cannot write " + option + " there");
  }
}

void writeFileAtomically(const std::string& path, std::string_view bytes) {
  const std::filesystem::path target(path);
  if (target.has_parent_path()) std::filesystem::create_directories(target.parent_path());
  AtomicFile file(path);
  file.write(bytes);
  file.commit();
}

}  // namespace marglab
