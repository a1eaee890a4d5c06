// Sequential bytes from a file (buffered reads, never the whole file in memory) or from memory,
// with the byte offset always known so errors can say where they happened.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace tessera::lod {

/// A byte buffer that is not zero-filled: a 4 MiB read buffer per open file must cost nothing
/// until it is read into.
class ReadBuffer {
 public:
  explicit ReadBuffer(size_t n = 0)
      : mData(std::make_unique_for_overwrite<uint8_t[]>(n)), mSize(n) {}
  uint8_t* data() { return mData.get(); }
  const uint8_t* data() const { return mData.get(); }
  size_t size() const { return mSize; }
  bool empty() const { return mSize == 0; }
  void swap(ReadBuffer& o) noexcept {
    std::swap(mData, o.mData);
    std::swap(mSize, o.mSize);
  }

 private:
  std::unique_ptr<uint8_t[]> mData;
  size_t mSize;
};

class ByteSource {
 public:
  /// Opens a file for reading. Throws ReadError naming `component` and the path.
  static ByteSource openFile(const std::filesystem::path& path, const std::string& component);
  /// Wraps bytes in memory; `bytes` must outlive the source.
  static ByteSource fromMemory(std::span<const uint8_t> bytes, std::string name);

  ByteSource(ByteSource&& other) noexcept;
  ByteSource& operator=(ByteSource&& other) noexcept;
  ByteSource(const ByteSource&) = delete;
  ByteSource& operator=(const ByteSource&) = delete;
  ~ByteSource();

  /// File name as given (used in messages).
  const std::string& name() const { return mName; }
  uint64_t size() const { return mSize; }
  /// Offset of the next byte to be consumed.
  uint64_t offset() const { return mWindowOffset + mPos; }
  bool atEnd() const { return offset() >= mSize; }

  /// Makes at least `n` bytes contiguous at `data()`, fewer only at end of file. Returns how
  /// many are available (<= the whole rest of the source). Cost: one read() per refill.
  size_t ensure(size_t n);
  const uint8_t* data() const { return mWindow + mPos; }
  void consume(size_t n) { mPos += n; }
  /// Copies up to `n` bytes; returns how many were copied.
  size_t read(void* dst, size_t n);
  /// Repositions the stream (used by LAS to jump to the point records).
  void seek(uint64_t offset);
  /// Back to byte 0 and line 0 (used to read a text file twice: sniff, then parse).
  void rewind() {
    seek(0);
    mLine = 0;
  }
  /// Reads bytes at an absolute offset without moving the stream (sampling). Returns count.
  size_t readAt(uint64_t offset, void* dst, size_t n) const;

  /// Next line without its terminator (\n or \r\n). False at end of input.
  /// Throws ReadError for a line longer than `max_line` bytes.
  bool readLine(std::string_view& line, size_t max_line = 1 << 20);
  /// 1-based number of the last line returned by readLine().
  uint64_t lineNumber() const { return mLine; }

 private:
  ByteSource() = default;
  void refill(size_t want);

  std::string mName;
  int mFd = -1;
  uint64_t mSize = 0;
  const uint8_t* mWindow = nullptr;  // memory: the bytes; file: mBuffer.data()
  size_t mWindowSize = 0;            // valid bytes in the window
  uint64_t mWindowOffset = 0;        // file offset of mWindow[0]
  size_t mPos = 0;                   // read position inside the window
  ReadBuffer mBuffer;
  uint64_t mLine = 0;
};

}  // namespace tessera::lod
