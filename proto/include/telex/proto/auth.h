// SPDX-License-Identifier: MIT
// Message authentication with a pre-shared key: truncated HMAC-SHA256 tags and a replay window.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <vector>

#include "telex/proto/messages.h"

namespace telex::proto {

// 128 bits of HMAC-SHA256: the truncation RFC 4868 deems fine for authentication (2^-128 forgery).
inline constexpr std::size_t kAuthTagBytes = 16;
inline constexpr std::size_t kMinKeyBytes = 16;
inline constexpr std::size_t kMaxKeyBytes = 1024;

// A pre-shared key. Its bytes are wiped when it goes away.
class AuthKey {
 public:
  // Throws std::invalid_argument when shorter than kMinKeyBytes or longer than kMaxKeyBytes.
  explicit AuthKey(std::span<const std::uint8_t> bytes);
  ~AuthKey();
  AuthKey(const AuthKey& other);
  AuthKey& operator=(const AuthKey& other);
  std::span<const std::uint8_t> bytes() const { return bytes_; }

 private:
  std::vector<std::uint8_t> bytes_;
};

// Reads the whole file as the key (raw bytes). One trailing newline (LF or CRLF) is dropped since
// editors and `openssl rand -hex 32 > key` add it; `head -c 32 /dev/urandom > key` is used as is.
// Throws std::runtime_error naming the path when it cannot be read, and
// std::invalid_argument naming it when the key is too short or too long.
AuthKey load_key_file(const std::filesystem::path& path);

// The 16-byte tag over `message` (header + payload, everything before the tag).
std::array<std::uint8_t, kAuthTagBytes> compute_tag(std::span<const std::uint8_t> message,
                                                    const AuthKey& key);

// Appends the tag over the current contents of `message`.
void append_tag(std::vector<std::uint8_t>& message, const AuthKey& key);

// The message without its tag when the tag matches (constant-time compare), nullopt otherwise
// (too short to hold a tag, wrong key, or any bit changed).
std::optional<std::span<const std::uint8_t>> verify_and_strip(std::span<const std::uint8_t> tagged,
                                                              const AuthKey& key);

// Anti-replay window over one sender's sequence numbers (one per session and direction), as in
// IPsec (RFC 4303 3.4.3): the highest sequence seen plus a bitmap of the kWindow before it. A
// sequence is accepted once; one older than the window is rejected as too old. Call it only after
// the tag verified, so forged sequence numbers cannot move the window.
class ReplayWindow {
 public:
  static constexpr std::uint64_t kWindow = 1024;
  enum class Verdict : std::uint8_t { Accepted, Replayed, TooOld };

  Verdict check_and_update(std::uint64_t seq);
  std::uint64_t highest() const { return highest_; }
  bool empty() const { return !any_; }

 private:
  bool test(std::uint64_t seq) const;
  void set(std::uint64_t seq);
  void clear(std::uint64_t seq);
  std::array<std::uint64_t, kWindow / 64> bits_{};
  std::uint64_t highest_ = 0;
  bool any_ = false;
};

// ---- the wire use (docs/PROTOCOL.md section 7) ----

// Header + payload with kFlagAuth set and the tag over both appended; without a key (nullptr) the
// plain encode(). The stream variant prefixes the u32 length of what follows (tag included).
std::vector<std::uint8_t> encode_sealed(const Header& header, const Message& message,
                                        const AuthKey* key);
std::vector<std::uint8_t> encode_stream_sealed(const Header& header, const Message& message,
                                               const AuthKey* key);

// The key of one session: HMAC-SHA256(psk, "telex-session-v1" | client_nonce | server_nonce |
// session_id), integers little-endian. Hello carries client_nonce (its header's capture_ns) and
// Accept carries server_nonce (its header's capture_ns) and session_id: a message recorded in
// another session does not verify in this one, whichever side replays it.
AuthKey derive_session_key(const AuthKey& psk, std::uint64_t client_nonce,
                           std::uint64_t server_nonce, std::uint32_t session_id);

// Throws std::invalid_argument naming the path when group or others may read or write the key
// file (its mode must be 0600 or 0400, as for ssh keys); std::runtime_error when it cannot stat.
void check_key_file_permissions(const std::filesystem::path& path);

// 64 bits from the operating system's random source (nonces, session ids).
std::uint64_t random_u64();

// Extends a 32-bit wire sequence number to 64 bits next to the highest one seen so far (serial
// arithmetic, RFC 1982), so a long session survives the u32 wrap.
std::uint64_t extend_seq(std::uint32_t wire_seq, std::uint64_t highest);

}  // namespace telex::proto
