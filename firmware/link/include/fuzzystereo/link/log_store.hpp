// Append-only binary device log (docs/protocol.md "Log files"). One file per boot and per
// rotation: <dir>/log_<id:06>.fsl.
//   header : "FSLOG\0\0\1" (8 bytes) | layout hash (8 bytes, protocol.toml)
//   record : length:u32 LE | crc:u32 LE = CRC-32C(body) | body
//   body   : t_ms:u32 LE | msg_id:u8 | payload of that message (protocol.toml)
// A file cut off mid-record (power cut) stays readable up to its last whole record.
#pragma once
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

namespace fs::link {

inline constexpr std::uint8_t kLogMagic[8] = {'F', 'S', 'L', 'O', 'G', 0, 0, 1};
inline constexpr std::size_t kLogHeaderSize = 16;

struct LogFileInfo {
  std::uint32_t id = 0;
  std::uint32_t size = 0;
};

class LogStore {
 public:
  // Opens a new file after the highest existing id; keeps at most `keep_files` files.
  LogStore(std::filesystem::path dir, std::size_t rotate_bytes, int keep_files);
  ~LogStore();
  LogStore(const LogStore&) = delete;
  LogStore& operator=(const LogStore&) = delete;

  // Appends one record (rotates first when the file would grow past rotate_bytes). False on an
  // I/O error (the record is lost and counted by the caller).
  bool append(std::uint32_t t_ms, std::uint8_t msg_id, const std::vector<std::uint8_t>& payload);
  std::vector<LogFileInfo> list() const;
  // Up to `length` bytes at `offset` of file `id`; `size` gets the file's current size.
  // Returns false when there is no such file.
  bool read(std::uint32_t id, std::uint32_t offset, std::size_t length, std::vector<std::uint8_t>& out,
            std::uint32_t& size) const;
  std::uint32_t current_id() const;

 private:
  void open_next();
  std::filesystem::path path_of(std::uint32_t id) const;
  std::filesystem::path dir_;
  std::size_t rotate_bytes_;
  int keep_files_;
  mutable std::mutex mu_;
  int fd_ = -1;
  std::uint32_t id_ = 0;
  std::size_t size_ = 0;
};

// Parses records from a log file image; stops at the first incomplete or corrupt record.
struct LogRecord {
  std::uint32_t t_ms = 0;
  std::uint8_t msg_id = 0;
  std::vector<std::uint8_t> payload;
};
struct LogParse {
  bool header_ok = false;
  std::vector<LogRecord> records;
  std::size_t good_bytes = 0;  // header + whole valid records
};
LogParse parse_log(const std::vector<std::uint8_t>& file);

}  // namespace fs::link
