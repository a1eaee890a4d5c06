// libFuzzer target: a chunk request (site.proto ChunkRequest) as the master's chunk server takes
// it (collab/chunk_server.h): parsed and checked (parseChunkRequest), then its range against
// stores of a few sizes (checkChunkRange). A refusal is the only failure allowed; what passes
// must name a store, ask for at most kMaxChunkRangeBytes, and lie within the store it passed
// for, so the server never reads outside a file or allocates what a site asks for unchecked; a
// withdrawal (cancel ids) names at most kMaxChunkCancelIds ids and no range.
#include <google/protobuf/stubs/logging.h>

#include <cstdint>
#include <cstdlib>
#include <string_view>

#include <tessera/collab/site_messages.h>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace tessera::collab;
  google::protobuf::LogSilencer quiet;
  tessera::site::ChunkRequest r;
  if (parseChunkRequest(std::string_view(reinterpret_cast<const char*>(data), size), r)) return 0;
  if (r.cancel_size() > 0) {  // a withdrawal: ids only, never a range
    if (size_t(r.cancel_size()) > kMaxChunkCancelIds || !r.store().empty() || r.offset() != 0 ||
        r.length() != 0)
      std::abort();
    return 0;
  }
  if (r.store().empty() || r.store().size() > kMaxStorePathBytes) std::abort();
  if (r.length() > kMaxChunkRangeBytes || r.offset() > UINT64_MAX - r.length()) std::abort();
  for (const uint64_t store_size : {uint64_t(0), uint64_t(1), uint64_t(746470), r.offset(),
                                    r.offset() + r.length(), UINT64_MAX}) {
    if (!checkChunkRange(r, store_size) && r.offset() + r.length() > store_size) std::abort();
  }
  return 0;
}
