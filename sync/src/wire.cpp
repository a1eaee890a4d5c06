#include <tessera/sync/wire.h>

#include <climits>

namespace tessera::sync {
namespace {

template <typename Message>
Message parse(std::string_view bytes, const char* fn) {
  Message message;
  // ParseFromArray takes an int size; larger input is not ours anyway.
  if (bytes.size() > size_t(INT_MAX) ||
      !message.ParseFromArray(bytes.data(), static_cast<int>(bytes.size()))) {
    throw SyncError(SyncError::Code::kParse, std::string(fn) + ": " + std::to_string(bytes.size()) +
                                                 " bytes are not a valid " +
                                                 message.GetDescriptor()->name() +
                                                 " (truncated or corrupt)");
  }
  message.DiscardUnknownFields();
  return message;
}

}  // namespace

std::string serializeFrame(const scene::Frame& frame) {
  return frame.SerializeAsString();
}

std::string serializeSnapshot(const scene::Snapshot& snapshot) {
  return snapshot.SerializeAsString();
}

scene::Frame parseFrame(std::string_view bytes) {
  return parse<scene::Frame>(bytes, "sync::parseFrame()");
}

scene::Snapshot parseSnapshot(std::string_view bytes) {
  return parse<scene::Snapshot>(bytes, "sync::parseSnapshot()");
}

}  // namespace tessera::sync
