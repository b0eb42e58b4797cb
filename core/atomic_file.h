// Atomic file output: write to a temporary name beside the destination, rename when complete.
// A failed or interrupted write never leaves a half-written file under the destination name.
#pragma once

#include <string>

namespace dnb {

class AtomicOutput {
 public:
  // The temporary name lives in the destination's folder (so rename is atomic) and keeps the
  // destination's extension (OpenImageIO chooses the format by extension).
  explicit AtomicOutput(std::string destination);
  ~AtomicOutput();  // removes the temporary file unless commit() succeeded
  AtomicOutput(const AtomicOutput&) = delete;
  AtomicOutput& operator=(const AtomicOutput&) = delete;

  const std::string& temp_path() const { return temp_; }
  const std::string& destination() const { return dest_; }
  // Flushes the temporary file to disk and renames it over the destination.
  void commit();

 private:
  std::string dest_;
  std::string temp_;
  bool committed_ = false;
};

// Writes `content` to `path` atomically. Throws WorkError naming the path on failure.
void write_text_atomic(const std::string& path, const std::string& content);
// Reads a whole file. Throws InputError naming the path when it cannot be read.
std::string read_text_file(const std::string& path);

}  // namespace dnb
