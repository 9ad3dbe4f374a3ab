#include "write/sqlite_write_behind.hpp"

#include <sqlite3.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "common/config_option.hpp"

namespace qtmv::write {

namespace {

constexpr std::size_t kBatchBytes = std::size_t{4} << 20;  // contiguous writes made one write of the file
constexpr std::size_t kQueuedBatches = 8;                  // how far (32 MiB) a connection may run ahead
// The most one write of the default VFS takes: SQLite's largest page (its unix VFS cuts a larger
// write short, to 17 bits, and reports a full disk).
constexpr std::size_t kWritePiece = 65536;

std::atomic<std::uint64_t> g_bytes{0};
std::atomic<std::uint64_t> g_waited_ns{0};
std::atomic<std::uint64_t> g_drains{0};

/// Adds the time since `start` to the connections' waiting.
void count_wait(std::chrono::steady_clock::time_point start) {
  g_waited_ns += static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - start).count());
}

/// The writes of one file, made on a thread of its own in the order they came. Every call on the
/// wrapped file, from either thread, holds file_lock(): the default VFS's files are not made for
/// two threads at once.
class FileWriter {
 public:
  FileWriter(sqlite3_file* file, std::uint64_t fail_after)
      : file_(file), fail_after_(fail_after), thread_([this] { run(); }) {}

  /// After drain(): stops the thread.
  ~FileWriter() {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    changed_.notify_all();
    thread_.join();
  }

  FileWriter(const FileWriter&) = delete;
  FileWriter& operator=(const FileWriter&) = delete;

  std::mutex& file_lock() { return file_lock_; }

  /// The first write that failed (SQLITE_OK while none has).
  int failure() const { return failure_.load(); }

  /// Queues `amount` bytes to be written at `offset` (the connection's thread).
  int write(const void* data, int amount, sqlite3_int64 offset) {
    if (const int rc = failure(); rc != SQLITE_OK) return rc;
    try {
      const auto n = static_cast<std::size_t>(amount);
      if (!current_.bytes.empty() && (offset != current_.end() || current_.bytes.size() + n > kBatchBytes)) {
        push();
      }
      if (current_.bytes.empty()) current_.offset = offset;
      const auto* bytes = static_cast<const unsigned char*>(data);
      current_.bytes.insert(current_.bytes.end(), bytes, bytes + n);
      if (current_.bytes.size() >= kBatchBytes) push();
    } catch (...) {
      fail(SQLITE_IOERR_NOMEM);  // no exception may cross SQLite: the write is lost, so all fail
    }
    return failure();
  }

  /// Waits until every write queued has reached the file (the connection's thread). Returns the
  /// first failure.
  int drain() {
    try {
      if (!current_.bytes.empty()) push();
    } catch (...) {
      fail(SQLITE_IOERR_NOMEM);
    }
    std::unique_lock<std::mutex> lock(mutex_);
    if (!queue_.empty() || busy_) {
      ++g_drains;
      const auto start = std::chrono::steady_clock::now();
      changed_.wait(lock, [&] { return queue_.empty() && !busy_; });
      count_wait(start);
    }
    return failure();
  }

  /// Whether bytes [offset, offset + amount) still wait, wholly or in part, to be written.
  bool waiting(sqlite3_int64 offset, int amount) {
    const auto overlaps = [&](sqlite3_int64 first, sqlite3_int64 end) {
      return first < end && offset < end && first < offset + amount;  // an empty range overlaps nothing
    };
    if (overlaps(current_.offset, current_.end())) return true;
    const std::lock_guard<std::mutex> lock(mutex_);
    if (busy_ && overlaps(in_flight_offset_, in_flight_end_)) return true;
    for (const Batch& b : queue_) {
      if (overlaps(b.offset, b.end())) return true;
    }
    return false;
  }

 private:
  /// Records the first failure: every call after it returns it, and what is queued is dropped.
  void fail(int rc) {
    int none = SQLITE_OK;
    failure_.compare_exchange_strong(none, rc);
  }

  struct Batch {
    sqlite3_int64 offset = 0;
    std::vector<unsigned char> bytes;
    sqlite3_int64 end() const { return offset + static_cast<sqlite3_int64>(bytes.size()); }
  };

  /// The batch being filled goes to the queue, once there is room; a spare one takes its place.
  void push() {
    std::unique_lock<std::mutex> lock(mutex_);
    if (queue_.size() >= kQueuedBatches) {
      const auto start = std::chrono::steady_clock::now();
      changed_.wait(lock, [&] { return queue_.size() < kQueuedBatches; });
      count_wait(start);
    }
    queue_.push_back(std::move(current_));
    current_ = Batch();
    if (!spare_.empty()) {
      current_.bytes = std::move(spare_.back());
      spare_.pop_back();
    }
    lock.unlock();
    changed_.notify_all();
    if (current_.bytes.capacity() < kBatchBytes) current_.bytes.reserve(kBatchBytes);
  }

  void run() {
    for (;;) {
      Batch batch;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        changed_.wait(lock, [&] { return stop_ || !queue_.empty(); });
        if (queue_.empty()) return;
        batch = std::move(queue_.front());
        queue_.pop_front();
        busy_ = true;
        in_flight_offset_ = batch.offset;
        in_flight_end_ = batch.end();
      }
      int rc = SQLITE_OK;
      if (failure() == SQLITE_OK) {  // after a failure, what is left is dropped
        const std::size_t n = batch.bytes.size();
        if (fail_after_ != 0 && written_ + n > fail_after_) {
          rc = SQLITE_FULL;
        } else {
          // In pieces of at most kWritePiece: the default VFS takes no more at once.
          for (std::size_t at = 0; at < n && rc == SQLITE_OK; at += kWritePiece) {
            const std::lock_guard<std::mutex> file(file_lock_);
            rc = file_->pMethods->xWrite(file_, batch.bytes.data() + at, static_cast<int>(std::min(kWritePiece, n - at)),
                                         batch.offset + static_cast<sqlite3_int64>(at));
          }
        }
        if (rc == SQLITE_OK) {
          written_ += n;
          g_bytes += n;
        }
      }
      {
        const std::lock_guard<std::mutex> lock(mutex_);
        if (rc != SQLITE_OK) fail(rc);
        busy_ = false;
        batch.bytes.clear();
        try {
          if (spare_.size() <= kQueuedBatches) spare_.push_back(std::move(batch.bytes));
        } catch (...) {
          // No room to keep the buffer for the next batch: it goes.
        }
      }
      changed_.notify_all();
    }
  }

  sqlite3_file* const file_;
  const std::uint64_t fail_after_;  // the fault switch's bytes; 0: none
  std::uint64_t written_ = 0;       // the thread's
  Batch current_;                   // the connection thread's
  std::mutex file_lock_;
  std::mutex mutex_;  // the rest
  std::condition_variable changed_;
  std::deque<Batch> queue_;
  std::vector<std::vector<unsigned char>> spare_;
  bool busy_ = false, stop_ = false;
  sqlite3_int64 in_flight_offset_ = 0, in_flight_end_ = 0;
  std::atomic<int> failure_{SQLITE_OK};
  std::thread thread_;  // last: it starts once the rest is made
};

/// A file opened through our VFS and written behind: the default VFS's file lies after it.
struct BehindFile {
  sqlite3_file base;  // pMethods: kBehindMethods
  sqlite3_file* real;
  FileWriter* writer;
  bool at_once;  // shared memory seen (WAL): writes made at once, as the default VFS makes them
  bool chunked;  // SQLITE_FCNTL_CHUNK_SIZE set: the file grows in chunks, at the size hints
  int sector_size, device_characteristics;  // the real file's, asked once (they are asked often)
};
constexpr std::size_t kRealOffset = (sizeof(BehindFile) + 15) / 16 * 16;

BehindFile& behind(sqlite3_file* f) { return *reinterpret_cast<BehindFile*>(f); }

/// Calls method `m` of the real file, holding the file lock.
template <class Method, class... Args>
int forward(BehindFile& f, Method m, Args... args) {
  const std::lock_guard<std::mutex> lock(f.writer->file_lock());
  return (f.real->pMethods->*m)(f.real, args...);
}

/// Calls method `m` of the real file once every write before has reached it.
template <class Method, class... Args>
int after_writes(BehindFile& f, Method m, Args... args) {
  if (const int rc = f.writer->drain(); rc != SQLITE_OK) return rc;
  return forward(f, m, args...);
}

int behind_close(sqlite3_file* file) {
  BehindFile& f = behind(file);
  const int rc = f.writer->drain();
  delete f.writer;
  f.writer = nullptr;
  const int closed = f.real->pMethods->xClose(f.real);
  file->pMethods = nullptr;
  return rc != SQLITE_OK ? rc : closed;
}

int behind_read(sqlite3_file* file, void* data, int amount, sqlite3_int64 offset) {
  BehindFile& f = behind(file);
  if (const int rc = f.writer->failure(); rc != SQLITE_OK) return rc;
  if (f.writer->waiting(offset, amount)) return after_writes(f, &sqlite3_io_methods::xRead, data, amount, offset);
  return forward(f, &sqlite3_io_methods::xRead, data, amount, offset);
}

int behind_write(sqlite3_file* file, const void* data, int amount, sqlite3_int64 offset) {
  BehindFile& f = behind(file);
  if (f.at_once) return forward(f, &sqlite3_io_methods::xWrite, data, amount, offset);
  return f.writer->write(data, amount, offset);
}

int behind_truncate(sqlite3_file* file, sqlite3_int64 size) {
  return after_writes(behind(file), &sqlite3_io_methods::xTruncate, size);
}

int behind_sync(sqlite3_file* file, int flags) { return after_writes(behind(file), &sqlite3_io_methods::xSync, flags); }

int behind_file_size(sqlite3_file* file, sqlite3_int64* size) {
  return after_writes(behind(file), &sqlite3_io_methods::xFileSize, size);
}

int behind_lock(sqlite3_file* file, int level) { return forward(behind(file), &sqlite3_io_methods::xLock, level); }

// The end of a lock lets other connections read the file: they must find every write there.
int behind_unlock(sqlite3_file* file, int level) {
  BehindFile& f = behind(file);
  const int rc = f.writer->drain();
  const int unlocked = forward(f, &sqlite3_io_methods::xUnlock, level);
  return rc != SQLITE_OK ? rc : unlocked;
}

int behind_check_reserved_lock(sqlite3_file* file, int* out) {
  return forward(behind(file), &sqlite3_io_methods::xCheckReservedLock, out);
}

// Every file control waits for the writes (SQLITE_FCNTL_SYNC stands for the sync that
// synchronous=OFF leaves out, and its failure fails the commit), but for those asked on every
// statement, transaction or spill of the cache that only tell about the file or grow it.
int behind_file_control(sqlite3_file* file, int op, void* arg) {
  BehindFile& f = behind(file);
  switch (op) {
    case SQLITE_FCNTL_SIZE_HINT:
      // At every spill that grows the file: the default VFS grows the file early only in chunks
      // (SQLITE_FCNTL_CHUNK_SIZE); without them nothing is asked of the file, and the file's lock,
      // which its thread holds while it writes, is not waited for.
      if (!f.chunked) return SQLITE_OK;
      return forward(f, &sqlite3_io_methods::xFileControl, op, arg);
    case SQLITE_FCNTL_CHUNK_SIZE:
      f.chunked = *static_cast<int*>(arg) > 0;
      return forward(f, &sqlite3_io_methods::xFileControl, op, arg);
    case SQLITE_FCNTL_LOCKSTATE:
    case SQLITE_FCNTL_HAS_MOVED:
    case SQLITE_FCNTL_VFSNAME:
    case SQLITE_FCNTL_VFS_POINTER:
    case SQLITE_FCNTL_BUSYHANDLER:
    case SQLITE_FCNTL_PDB:
    case SQLITE_FCNTL_LAST_ERRNO:
    case SQLITE_FCNTL_TEMPFILENAME:
      return forward(f, &sqlite3_io_methods::xFileControl, op, arg);
    default:
      return after_writes(f, &sqlite3_io_methods::xFileControl, op, arg);
  }
}

int behind_sector_size(sqlite3_file* file) { return behind(file).sector_size; }

int behind_device_characteristics(sqlite3_file* file) { return behind(file).device_characteristics; }

// Shared memory means WAL: other connections then read the file beside this one's lock, so its
// writes go straight to it from here on.
int shared_memory(BehindFile& f) {
  if (!f.at_once) {
    if (const int rc = f.writer->drain(); rc != SQLITE_OK) return rc;
    f.at_once = true;
  }
  return SQLITE_OK;
}

int behind_shm_map(sqlite3_file* file, int region, int size, int extend, void volatile** out) {
  BehindFile& f = behind(file);
  if (const int rc = shared_memory(f); rc != SQLITE_OK) return rc;
  return forward(f, &sqlite3_io_methods::xShmMap, region, size, extend, out);
}

int behind_shm_lock(sqlite3_file* file, int offset, int n, int flags) {
  BehindFile& f = behind(file);
  if (const int rc = shared_memory(f); rc != SQLITE_OK) return rc;
  return forward(f, &sqlite3_io_methods::xShmLock, offset, n, flags);
}

void behind_shm_barrier(sqlite3_file* file) {
  BehindFile& f = behind(file);
  const std::lock_guard<std::mutex> lock(f.writer->file_lock());
  f.real->pMethods->xShmBarrier(f.real);
}

int behind_shm_unmap(sqlite3_file* file, int delete_flag) {
  return forward(behind(file), &sqlite3_io_methods::xShmUnmap, delete_flag);
}

// Version 2: no xFetch, so SQLite never reads the file through a memory map, which would not see
// the writes still queued.
const sqlite3_io_methods kBehindMethods = {
    2,
    behind_close,
    behind_read,
    behind_write,
    behind_truncate,
    behind_sync,
    behind_file_size,
    behind_lock,
    behind_unlock,
    behind_check_reserved_lock,
    behind_file_control,
    behind_sector_size,
    behind_device_characteristics,
    behind_shm_map,
    behind_shm_lock,
    behind_shm_barrier,
    behind_shm_unmap,
    nullptr,
    nullptr,
};

/// The VFS (made the default while a guard lives), the files it writes behind, and the default
/// VFS it wraps (the first one seen, kept for the process: connections opened through ours call it).
struct Registry {
  std::mutex mutex;
  std::multiset<std::string> paths;  // full path names, as SQLite hands them to xOpen
  int guards = 0;
  sqlite3_vfs* real = nullptr;
  sqlite3_vfs vfs{};
};

Registry& registry() {
  static Registry& r = *new Registry;  // never destroyed: connections opened through it may outlive main
  return r;
}

sqlite3_vfs* real_vfs() { return registry().real; }

bool written_behind(const char* name) {
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.mutex);
  return r.paths.count(name) > 0;
}

std::uint64_t fault_bytes() {
  const std::string fault = fault_switch(SqliteWriteBehind::kFaultBytes);
  return fault.empty() ? 0 : std::stoull(fault);
}

int open_file(sqlite3_vfs*, const char* name, sqlite3_file* file, int flags, int* out_flags) {
  sqlite3_vfs* real = real_vfs();
  if (name == nullptr || (flags & SQLITE_OPEN_MAIN_DB) == 0 || !written_behind(name)) {
    return real->xOpen(real, name, file, flags, out_flags);  // the real file in place of ours
  }
  BehindFile& f = behind(file);
  f = BehindFile{};
  f.real = reinterpret_cast<sqlite3_file*>(reinterpret_cast<unsigned char*>(file) + kRealOffset);
  const int rc = real->xOpen(real, name, f.real, flags, out_flags);
  if (rc != SQLITE_OK || f.real->pMethods == nullptr) {
    file->pMethods = nullptr;  // SQLite closes nothing then
    return rc != SQLITE_OK ? rc : SQLITE_CANTOPEN;
  }
  f.sector_size = f.real->pMethods->xSectorSize(f.real);
  f.device_characteristics = f.real->pMethods->xDeviceCharacteristics(f.real);
  try {
    f.writer = new FileWriter(f.real, fault_bytes());
  } catch (const std::exception&) {
    f.real->pMethods->xClose(f.real);
    file->pMethods = nullptr;
    return SQLITE_CANTOPEN;
  }
  file->pMethods = &kBehindMethods;
  return SQLITE_OK;
}

/// Makes our VFS, wrapping the default one; every method but xOpen is the default's.
void make_vfs(Registry& r) {
  sqlite3_vfs& v = r.vfs;
  sqlite3_vfs* real = r.real;
  v.iVersion = std::min(real->iVersion, 3);
  v.szOsFile = static_cast<int>(kRealOffset) + real->szOsFile;
  v.mxPathname = real->mxPathname;
  v.zName = "qtmv-write-behind";
  v.xOpen = open_file;
  v.xDelete = [](sqlite3_vfs*, const char* name, int sync) { return real_vfs()->xDelete(real_vfs(), name, sync); };
  v.xAccess = [](sqlite3_vfs*, const char* name, int flags, int* out) {
    return real_vfs()->xAccess(real_vfs(), name, flags, out);
  };
  v.xFullPathname = [](sqlite3_vfs*, const char* name, int n, char* out) {
    return real_vfs()->xFullPathname(real_vfs(), name, n, out);
  };
  v.xDlOpen = [](sqlite3_vfs*, const char* name) { return real_vfs()->xDlOpen(real_vfs(), name); };
  v.xDlError = [](sqlite3_vfs*, int n, char* out) { real_vfs()->xDlError(real_vfs(), n, out); };
  v.xDlSym = [](sqlite3_vfs*, void* handle, const char* symbol) {
    return real_vfs()->xDlSym(real_vfs(), handle, symbol);
  };
  v.xDlClose = [](sqlite3_vfs*, void* handle) { real_vfs()->xDlClose(real_vfs(), handle); };
  v.xRandomness = [](sqlite3_vfs*, int n, char* out) { return real_vfs()->xRandomness(real_vfs(), n, out); };
  v.xSleep = [](sqlite3_vfs*, int us) { return real_vfs()->xSleep(real_vfs(), us); };
  v.xCurrentTime = [](sqlite3_vfs*, double* out) { return real_vfs()->xCurrentTime(real_vfs(), out); };
  v.xGetLastError = [](sqlite3_vfs*, int n, char* out) { return real_vfs()->xGetLastError(real_vfs(), n, out); };
  if (v.iVersion >= 2) {
    v.xCurrentTimeInt64 = [](sqlite3_vfs*, sqlite3_int64* out) {
      return real_vfs()->xCurrentTimeInt64(real_vfs(), out);
    };
  }
  if (v.iVersion >= 3) {
    v.xSetSystemCall = [](sqlite3_vfs*, const char* name, sqlite3_syscall_ptr call) {
      return real_vfs()->xSetSystemCall(real_vfs(), name, call);
    };
    v.xGetSystemCall = [](sqlite3_vfs*, const char* name) { return real_vfs()->xGetSystemCall(real_vfs(), name); };
    v.xNextSystemCall = [](sqlite3_vfs*, const char* name) { return real_vfs()->xNextSystemCall(real_vfs(), name); };
  }
}

}  // namespace

SqliteWriteBehind::SqliteWriteBehind(const std::string& path) {
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.mutex);
  if (sqlite3_initialize() != SQLITE_OK) throw std::runtime_error("SQLite cannot be initialised");
  if (r.real == nullptr) {
    r.real = sqlite3_vfs_find(nullptr);
    if (r.real == nullptr) throw std::runtime_error("SQLite has no default file system");
    make_vfs(r);
  }
  std::vector<char> full(static_cast<std::size_t>(r.real->mxPathname) + 1);
  // Without a full name to match, the file is written at once (full_path_ stays empty).
  if (r.real->xFullPathname(r.real, path.c_str(), static_cast<int>(full.size()), full.data()) != SQLITE_OK) return;
  full_path_ = full.data();
  if (r.guards++ == 0) sqlite3_vfs_register(&r.vfs, 1);
  r.paths.insert(full_path_);
}

SqliteWriteBehind::~SqliteWriteBehind() {
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.mutex);
  if (full_path_.empty()) return;
  r.paths.erase(r.paths.find(full_path_));
  // The default VFS is the real one again; ours stays registered for the connections it opened.
  if (--r.guards == 0) sqlite3_vfs_register(r.real, 1);
}

SqliteWriteBehind::Totals SqliteWriteBehind::totals() {
  return {g_bytes.load(), static_cast<double>(g_waited_ns.load()) * 1e-9, g_drains.load()};
}

}  // namespace qtmv::write
