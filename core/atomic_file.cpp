#include "core/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <fmt/format.h>

#include "core/errors.h"

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
  std::string name = fmt::format(".{}.tmp-{}-{}{}", p.stem().string(), ::getpid(), g_counter++,
                                 p.extension().string());
  temp_ = (dir / name).string();
}

AtomicOutput::~AtomicOutput() {
  if (!committed_) {
    std::error_code ec;
    fs::remove(temp_, ec);
  }
}

void AtomicOutput::commit() {
  // fsync so that a crash right after the rename cannot expose an empty file.
  int fd = ::open(temp_.c_str(), O_RDONLY);
  if (fd < 0)
    throw WorkError(fmt::format("writing '{}': temporary file '{}' is missing", dest_, temp_));
  ::fsync(fd);
  ::close(fd);
  if (std::rename(temp_.c_str(), dest_.c_str()) != 0)
    throw WorkError(fmt::format("cannot rename '{}' to '{}': {}", temp_, dest_, std::strerror(errno)));
  committed_ = true;
}

void write_text_atomic(const std::string& path, const std::string& content) {
  AtomicOutput out(path);
  {
    std::ofstream f(out.temp_path(), std::ios::binary);
    f << content;
    f.flush();
    if (!f) throw WorkError(fmt::format("cannot write '{}'", path));
  }
  out.commit();
}

std::string read_text_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(fmt::format("cannot read '{}': {}", path, std::strerror(errno)));
  std::ostringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

}  // namespace dnb
