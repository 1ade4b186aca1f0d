// SPDX-License-Identifier: MIT
// The link's refused messages (link_drops.h).
#include "link_drops.h"

namespace telex::local {

proto::Result unopened(proto::OpenError why) {
  proto::Result bad;
  bad.error = why == proto::OpenError::AuthFailed ? proto::ErrorReason::AuthFailed
              : why == proto::OpenError::Replayed ? proto::ErrorReason::Replayed
                                                  : proto::ErrorReason::Unsealed;
  bad.detail = proto::open_error_name(why).data();  // a string literal
  return bad;
}

void count_link_drop(ClientStats& stats, const proto::Result& r) {
  switch (r.error) {
    case proto::ErrorReason::AuthFailed:
      stats.auth_failed.fetch_add(1);
      break;
    case proto::ErrorReason::Unsealed:
      stats.unsealed.fetch_add(1);
      break;
    case proto::ErrorReason::Replayed:
      stats.replayed.fetch_add(1);
      break;
    default:
      stats.dropped_malformed.fetch_add(1);
      break;
  }
}

std::string link_drop_warning(const ClientStats& stats, const proto::Result& r,
                              const char* transport) {
  return "dropped a " + std::string(transport) +
         " message from the remote: " + std::string(proto::error_reason_name(r.error)) + " (" +
         r.detail + "); totals: auth_failed " + std::to_string(stats.auth_failed.load()) +
         " unsealed " + std::to_string(stats.unsealed.load()) + " replayed " +
         std::to_string(stats.replayed.load()) + " malformed " +
         std::to_string(stats.dropped_malformed.load());
}

}  // namespace telex::local
