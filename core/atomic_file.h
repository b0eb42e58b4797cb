// Atomic, durable file output: write to a temporary name beside the destination, check that
// every byte reached the file, then rename. A failed or interrupted write never leaves a
// half-written file under the destination name, and a write that failed (a full disk, a
// quota, an I/O error) is reported with the system's reason, never silently committed.
//
//   AtomicOutput out("dir/result.json");
//   out.write(bytes.data(), bytes.size());   // every write(2), fsync(2) and close(2) checked
//   out.commit();                            // rename, then fsync the folder
//
// Writers that can encode to memory (OpenImageIO through an IOProxy, cv::imencode, text) hand
// the bytes to write(); the temporary file is then written by this class alone.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

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
  // Writes `size` bytes as the whole temporary file and makes them durable: every write, the
  // fsync and the close are checked; WorkError naming the destination and the system's reason
  // (e.g. "No space left on device") otherwise.
  void write(const void* data, std::size_t size);
  void write(const std::string& bytes) { write(bytes.data(), bytes.size()); }
  // For writers that stream and seek (OpenImageIO through an IOProxy: OpenEXR writes its chunk
  // offset table last, at the front): writes `size` bytes at `offset` of the temporary file, every
  // pwrite(2) checked; finish_writes() then fsyncs and closes it (both checked). WorkError naming
  // the destination and the system's reason, as write(). Not to be mixed with write().
  void write_at(const void* data, std::size_t size, std::uint64_t offset);
  void finish_writes();
  // Renames the temporary file over the destination and fsyncs the folder. When write() was not
  // used (another library wrote temp_path() itself), the file is fsynced first and must not be
  // empty. WorkError with the system's reason on any failure.
  void commit();

 private:
  std::string dest_;
  std::string temp_;
  bool written_ = false;
  bool committed_ = false;
  int stream_fd_ = -1;  // write_at's open temporary file, until finish_writes()
};

// Writes `content` to `path` atomically and durably. Throws WorkError naming the path and the
// system's reason on failure.
void write_text_atomic(const std::string& path, const std::string& content);
// How keep_file put a file in place.
enum class Kept {
  Linked,     // a new hard link to the source
  Copied,     // a copy (the hard link failed: another file system, or allow_link false)
  Unchanged,  // the destination already was the source (same inode) or held the same bytes
};
const char* to_string(Kept k);  // "linked", "copied", "unchanged"

// Puts the exact bytes of `source` (contents, metadata, everything) at `destination`: a hard
// link where the file system allows one, else a copy, either way atomically and durably like
// every other write (a temporary name beside the destination, fsync, rename, fsync of the
// folder). Nothing is written when the destination already is the source's inode or holds the
// same bytes (size, then SHA-256), so that keeping the same file twice neither re-copies nor
// duplicates it. A hard link shares the inode: a later in-place edit of either name shows in
// both (the harness only ever replaces files by rename). `allow_link` false always copies (the
// fallback, testable on one file system). InputError naming `source` when it cannot be read,
// WorkError naming `destination` when it cannot be written.
Kept keep_file(const std::string& source, const std::string& destination, bool allow_link = true);

// Removes the temporary files AtomicOutput left in `dir` (recursively) when their writer died
// before committing or removing them (a kill -9): names of the form ".NAME.tmp-PID-N.EXT" whose
// process PID no longer runs. Returns how many were removed.
std::size_t remove_stale_temporaries(const std::string& dir);

// An exclusive advisory lock (flock) on DIR/.lock, held for the object's lifetime and released
// by the system if the process dies. A second holder waits; `waiting` is called once with the
// process id the lock file names (written by the holder) before it waits.
class FolderLock {
 public:
  FolderLock(const std::string& dir, const std::function<void(const std::string& holder)>& waiting = {});
  ~FolderLock();
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;

 private:
  int fd_ = -1;
};

// The processes of one run into DIR (every MPI rank, or the one process) each hold a shared flock
// on DIR/.run.lock for their lifetime. The run's first process (`first`, before any other of the
// run starts) takes it exclusively before sharing it, and so waits, calling `waiting` once, until
// every process of an earlier run into DIR has ended. Why: a SIGKILL to `mpirun` does not reach
// its ranks (OpenMPI gives each rank a process group of its own), which run on for a moment and
// still write the folder's spool; a run started again at once would read it under them.
class RunLock {
 public:
  RunLock(const std::string& dir, bool first, const std::function<void()>& waiting = {});
  ~RunLock();
  RunLock(const RunLock&) = delete;
  RunLock& operator=(const RunLock&) = delete;

 private:
  int fd_ = -1;
};

// Creates `dir` and its parents where missing (an output folder); WorkError "cannot create
// folder 'DIR': REASON" (the system's) otherwise, e.g. when a file holds one of the names.
void create_folder(const std::string& dir);

// Refuses an output that is one of the command's inputs (the same file, also through a link):
// writing it would replace the input, which is then lost (`denoise am f.exr -o f.exr`). Each
// input is (what it is, its path), e.g. {"frame", "f.exr"}; inputs that do not exist are
// skipped. InputError "'OUT': is the FRAME 'IN' itself: ..." otherwise.
void require_output_is_not_input(const std::string& output,
                                 const std::vector<std::pair<std::string, std::string>>& inputs);

// Reads a whole file. Throws InputError naming the path when it cannot be read.
std::string read_text_file(const std::string& path);

}  // namespace dnb
