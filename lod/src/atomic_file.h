// A file written to PATH.partial and renamed into place on commit(): a failed or interrupted
// write never leaves a half-written file under the name asked for.
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <tessera/lod/point_writer.h>

namespace tessera::lod {

/// Writes to PATH.partial then renames: readers never see a half-written file.
class AtomicFile {
 public:
  AtomicFile(std::filesystem::path path, const char* component)
      : mPath(std::move(path)),
        mTmp(mPath.string() + ".partial"),
        mComponent(component),
        mOut(mTmp, std::ios::binary | std::ios::trunc) {
    if (!mOut) throw WriteError(std::string(mComponent) + ": cannot create " + mTmp.string());
  }
  ~AtomicFile() {
    if (!mDone) {
      std::error_code ec;
      std::filesystem::remove(mTmp, ec);
    }
  }
  void write(const std::vector<uint8_t>& b) { write(b.data(), b.size()); }
  void write(const uint8_t* data, size_t n) {
    mOut.write(reinterpret_cast<const char*>(data), std::streamsize(n));
    if (!mOut)
      throw WriteError(std::string(mComponent) + ": write failed for " + mTmp.string() +
                       " (disk full?)");
    mWritten += n;
  }
  /// Bytes written so far (the offset the next write lands at).
  uint64_t written() const { return mWritten; }
  /// Overwrites bytes already written (a header field known only at the end).
  void patch(uint64_t offset, const void* data, size_t n) {
    mOut.seekp(std::streamoff(offset));
    mOut.write(static_cast<const char*>(data), std::streamsize(n));
    mOut.seekp(std::streamoff(mWritten));
    if (!mOut)
      throw WriteError(std::string(mComponent) + ": write failed for " + mTmp.string() +
                       " (disk full?)");
  }
  void commit() {
    mOut.close();
    if (!mOut) throw WriteError(std::string(mComponent) + ": closing " + mTmp.string() + " failed");
    std::error_code ec;
    std::filesystem::rename(mTmp, mPath, ec);
    if (ec)
      throw WriteError(std::string(mComponent) + ": cannot rename to " + mPath.string() + ": " +
                       ec.message());
    mDone = true;
  }

 private:
  std::filesystem::path mPath, mTmp;
  const char* mComponent;
  std::ofstream mOut;
  uint64_t mWritten = 0;
  bool mDone = false;
};

}  // namespace tessera::lod
