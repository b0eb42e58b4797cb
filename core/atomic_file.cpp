#include "core/atomic_file.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "core/errors.h"
#include "core/hash.h"

namespace dnb {
namespace fs = std::filesystem;

static std::atomic<int> g_counter{0};

AtomicOutput::AtomicOutput(std::string destination) : dest_(std::move(destination)) {
  fs::path p(dest_);
  fs::path dir = p.parent_path();
  if (!dir.empty() && !fs::exists(dir)) {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) throw WorkError(fmt::format("cannot create folder '{}' for '{}': {}", dir.string(), dest_, ec.message()));
  }
  // Refused here, before anything is staged: found only at the rename, a frame's edge file would
  // already be committed beside a frame that never comes.
  if (!dir.empty() && !fs::is_directory(dir))
    throw WorkError(fmt::format("cannot write '{}': '{}': {}", dest_, dir.string(), std::strerror(ENOTDIR)));
  if (fs::is_directory(p)) throw WorkError(fmt::format("cannot write '{}': {}", dest_, std::strerror(EISDIR)));
  std::string name = fmt::format(".{}.tmp-{}-{}{}", p.stem().string(), ::getpid(), g_counter++,
                                 p.extension().string());
  temp_ = (dir / name).string();
}

AtomicOutput::~AtomicOutput() {
  if (stream_fd_ >= 0) ::close(stream_fd_);
  if (!committed_) {
    std::error_code ec;
    fs::remove(temp_, ec);
  }
}

namespace {

std::string reason() { return std::strerror(errno); }

// fsync of the folder holding `path`, so that the rename itself survives a crash.
void sync_folder(const std::string& path) {
  fs::path dir = fs::path(path).parent_path();
  if (dir.empty()) dir = ".";
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) throw WorkError(fmt::format("writing '{}': cannot open its folder to sync it: {}", path, reason()));
  const int rc = ::fsync(fd);
  const std::string why = rc == 0 ? "" : reason();
  ::close(fd);
  // Some file systems refuse fsync on a folder (EINVAL): the rename is then as durable as they make it.
  if (rc != 0 && errno != EINVAL) throw WorkError(fmt::format("writing '{}': cannot sync its folder: {}", path, why));
}

}  // namespace

void AtomicOutput::write(const void* data, std::size_t size) {
  write_at(data, size, 0);  // opens (and truncates) the temporary file also for size 0
  finish_writes();
}

void AtomicOutput::write_at(const void* data, std::size_t size, std::uint64_t offset) {
  if (stream_fd_ < 0) {
    stream_fd_ = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (stream_fd_ < 0) throw WorkError(fmt::format("cannot write '{}': {}", dest_, reason()));
  }
  const char* p = static_cast<const char*>(data);
  std::size_t left = size;
  while (left > 0) {
    const ssize_t n = ::pwrite(stream_fd_, p, left, off_t(offset + (size - left)));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw WorkError(fmt::format("cannot write '{}' ({} of {} bytes at offset {} written): {}", dest_, size - left, size,
                                  offset, n < 0 ? reason() : "no progress"));
    p += n;
    left -= std::size_t(n);
  }
}

void AtomicOutput::finish_writes() {
  if (stream_fd_ < 0) throw WorkError(fmt::format("cannot write '{}': nothing was written", dest_));
  const int fd = stream_fd_;
  stream_fd_ = -1;
  if (::fsync(fd) != 0) {
    const std::string why = reason();
    ::close(fd);
    throw WorkError(fmt::format("cannot write '{}': fsync failed: {}", dest_, why));
  }
  if (::close(fd) != 0) throw WorkError(fmt::format("cannot write '{}': close failed: {}", dest_, reason()));
  written_ = true;
}

void AtomicOutput::commit() {
  if (!written_) {
    // Written by another library: make it durable here and refuse an empty file (what a writer
    // that lost its data to a full disk leaves behind).
    const int fd = ::open(temp_.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw WorkError(fmt::format("writing '{}': temporary file '{}' is missing: {}", dest_, temp_, reason()));
    struct stat st {};
    const bool empty = ::fstat(fd, &st) == 0 && st.st_size == 0;
    const int rc = ::fsync(fd);
    const std::string why = rc == 0 ? "" : reason();
    ::close(fd);
    if (rc != 0) throw WorkError(fmt::format("cannot write '{}': fsync failed: {}", dest_, why));
    if (empty) throw WorkError(fmt::format("cannot write '{}': the writer left an empty file", dest_));
  }
  if (std::rename(temp_.c_str(), dest_.c_str()) != 0)
    throw WorkError(fmt::format("cannot write '{}': renaming its temporary file failed: {}", dest_, reason()));
  committed_ = true;
  sync_folder(dest_);
}

void write_text_atomic(const std::string& path, const std::string& content) {
  AtomicOutput out(path);
  out.write(content);
  out.commit();
}

const char* to_string(Kept k) {
  switch (k) {
    case Kept::Linked: return "linked";
    case Kept::Copied: return "copied";
    case Kept::Unchanged: return "unchanged";
  }
  return "unchanged";
}

namespace {

// Whether `a` and `b` hold the same bytes: the same inode, or the same size and SHA-256.
bool same_bytes(const std::string& a, const std::string& b) {
  std::error_code ec;
  if (!fs::is_regular_file(b, ec)) return false;
  if (fs::equivalent(a, b, ec)) return true;
  if (fs::file_size(a, ec) != fs::file_size(b, ec) || ec) return false;
  return sha256_file(a) == sha256_file(b);
}

}  // namespace

Kept keep_file(const std::string& source, const std::string& destination, bool allow_link) {
  std::error_code ec;
  if (!fs::is_regular_file(source, ec))
    throw InputError(fmt::format("cannot keep '{}' as '{}': it is not a readable file", source, destination));
  if (same_bytes(source, destination)) return Kept::Unchanged;
  AtomicOutput out(destination);
  // Not linked straight to the destination: link(2) refuses an existing name, and a rename over
  // it is what keeps a reader from ever seeing the destination missing.
  Kept how = Kept::Linked;
  if (!allow_link || ::link(source.c_str(), out.temp_path().c_str()) != 0) {
    how = Kept::Copied;
    fs::copy_file(source, out.temp_path(), fs::copy_options::overwrite_existing, ec);
    if (ec) throw WorkError(fmt::format("cannot copy '{}' to '{}': {}", source, destination, ec.message()));
  }
  out.commit();  // fsyncs the file (a link or a copy alike), renames, fsyncs the folder
  return how;
}

std::size_t remove_stale_temporaries(const std::string& dir) {
  std::size_t removed = 0;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const auto tmp = name.find(".tmp-");
    if (name.empty() || name[0] != '.' || tmp == std::string::npos || !it->is_regular_file()) continue;
    const long pid = std::strtol(name.c_str() + tmp + 5, nullptr, 10);
    if (pid <= 0 || pid == ::getpid() || ::kill(pid_t(pid), 0) == 0 || errno != ESRCH) continue;
    std::error_code rm;
    if (fs::remove(it->path(), rm)) ++removed;
  }
  return removed;
}

namespace {

// DIR/NAME opened for flock (the folder and the file created where missing).
int open_lock_file(const std::string& dir, const char* name, std::string& path) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  path = dir + "/" + name;
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) throw WorkError(fmt::format("cannot open the lock '{}': {}", path, std::strerror(errno)));
  return fd;
}

// flock(fd, how); false when `how` holds LOCK_NB and another process holds the lock. Closes
// `fd` before throwing (a constructor that throws runs no destructor).
bool lock_file(int fd, int how, const std::string& path) {
  while (::flock(fd, how) != 0) {
    if (errno == EINTR) continue;
    if ((how & LOCK_NB) && errno == EWOULDBLOCK) return false;
    const int e = errno;
    ::close(fd);
    throw WorkError(fmt::format("cannot lock '{}': {}", path, std::strerror(e)));
  }
  return true;
}

}  // namespace

FolderLock::FolderLock(const std::string& dir, const std::function<void(const std::string&)>& waiting) {
  std::string path;
  fd_ = open_lock_file(dir, ".lock", path);
  if (!lock_file(fd_, LOCK_EX | LOCK_NB, path)) {
    if (waiting) {
      char buf[64] = {};
      const ssize_t n = ::pread(fd_, buf, sizeof buf - 1, 0);
      waiting(n > 0 ? std::string(buf, std::size_t(n)) : std::string("another process"));
    }
    lock_file(fd_, LOCK_EX, path);
  }
  const std::string me = fmt::format("process {}", ::getpid());
  if (::ftruncate(fd_, 0) != 0 || ::pwrite(fd_, me.data(), me.size(), 0) != ssize_t(me.size())) {
    // The holder's name is a courtesy for the waiting run's message; the lock holds without it.
  }
}

FolderLock::~FolderLock() {
  if (fd_ >= 0) ::close(fd_);  // releases the flock
}

RunLock::RunLock(const std::string& dir, bool first, const std::function<void()>& waiting) {
  std::string path;
  fd_ = open_lock_file(dir, ".run.lock", path);
  if (first && !lock_file(fd_, LOCK_EX | LOCK_NB, path)) {
    if (waiting) waiting();
    lock_file(fd_, LOCK_EX, path);
  }
  // From exclusive to shared: flock(2) converts in place; the other processes of this run then
  // share it (they start after this one, behind a barrier).
  lock_file(fd_, LOCK_SH, path);
}

RunLock::~RunLock() {
  if (fd_ >= 0) ::close(fd_);  // releases the flock
}

void create_folder(const std::string& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw WorkError(fmt::format("cannot create folder '{}': {}", dir, ec.message()));
}

void require_output_is_not_input(const std::string& output,
                                 const std::vector<std::pair<std::string, std::string>>& inputs) {
  for (const auto& [what, input] : inputs) {
    std::error_code ec;
    // fs::equivalent compares device and inode: the same file also through a symbolic or hard
    // link. An output that does not exist yet cannot be an existing input (ec is set, false).
    if (!input.empty() && fs::equivalent(output, input, ec) && !ec)
      throw InputError(fmt::format("'{}': is the {} '{}' itself: writing it would replace the input; choose another "
                                   "output file",
                                   output, what, input));
  }
}

std::string read_text_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(fmt::format("cannot read '{}': {}", path, std::strerror(errno)));
  std::ostringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

}  // namespace dnb
