#include <tessera/sync/cluster_link.h>

#include <climits>

namespace tessera::sync {

namespace {

template <typename Envelope>
bool parseEnvelope(std::string_view bytes, Envelope& out, std::string& why) {
  out.Clear();
  if (bytes.size() > size_t(INT_MAX) || !out.ParseFromArray(bytes.data(), int(bytes.size()))) {
    why = std::to_string(bytes.size()) + " bytes are not a " + out.GetDescriptor()->name() +
          " (not a Tessera cluster peer, or a corrupt message)";
    return false;
  }
  out.DiscardUnknownFields();
  if (out.protocol() != kProtocolVersion) {
    why = "protocol version " + std::to_string(out.protocol()) + ", this build speaks " +
          std::to_string(kProtocolVersion) + " (run the same Tessera version on every host)";
    return false;
  }
  if (out.kind_case() == 0) {
    why = std::string("a ") + out.GetDescriptor()->name() + " without a message kind";
    return false;
  }
  return true;
}

}  // namespace

void LinkEvents::append(LinkEvents&& more) {
  for (auto& j : more.joins) joins.push_back(std::move(j));
  for (auto& r : more.reports) reports.push_back(std::move(r));
  for (auto& f : more.faults) faults.push_back(std::move(f));
  gone.insert(more.gone.begin(), more.gone.end());
  stalled.insert(more.stalled.begin(), more.stalled.end());
}

std::string envelope(cluster::ToNode message) {
  message.set_protocol(kProtocolVersion);
  return message.SerializeAsString();
}

std::string envelope(cluster::FromNode message) {
  message.set_protocol(kProtocolVersion);
  return message.SerializeAsString();
}

bool parseFromNode(std::string_view bytes, cluster::FromNode& out, std::string& why) {
  return parseEnvelope(bytes, out, why);
}

bool parseToNode(std::string_view bytes, cluster::ToNode& out, std::string& why) {
  return parseEnvelope(bytes, out, why);
}

}  // namespace tessera::sync
