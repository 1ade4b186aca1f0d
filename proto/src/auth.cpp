// SPDX-License-Identifier: MIT
// HMAC-SHA256 message tags (OpenSSL), constant-time verification, key files and the replay window.
#include "telex/proto/auth.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <openssl/rand.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>

#include "byte_io.h"

namespace telex::proto {

AuthKey::AuthKey(std::span<const std::uint8_t> bytes) : bytes_(bytes.begin(), bytes.end()) {
  if (bytes_.size() < kMinKeyBytes)
    throw std::invalid_argument("pre-shared key is " + std::to_string(bytes_.size()) +
                                " bytes; at least " + std::to_string(kMinKeyBytes) + " are needed");
  if (bytes_.size() > kMaxKeyBytes)
    throw std::invalid_argument("pre-shared key is " + std::to_string(bytes_.size()) +
                                " bytes; at most " + std::to_string(kMaxKeyBytes) + " are allowed");
}

AuthKey::~AuthKey() {
  if (!bytes_.empty()) OPENSSL_cleanse(bytes_.data(), bytes_.size());
}

AuthKey::AuthKey(const AuthKey& other) = default;

AuthKey& AuthKey::operator=(const AuthKey& other) {
  if (this != &other) {
    if (!bytes_.empty()) OPENSSL_cleanse(bytes_.data(), bytes_.size());
    bytes_ = other.bytes_;
  }
  return *this;
}

AuthKey load_key_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read pre-shared key file '" + path.string() + "'");
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
  if (in.bad())
    throw std::runtime_error("error reading pre-shared key file '" + path.string() + "'");
  // One trailing newline is an editor's, not the key's.
  if (!bytes.empty() && bytes.back() == '\n') {
    bytes.pop_back();
    if (!bytes.empty() && bytes.back() == '\r') bytes.pop_back();
  }
  try {
    AuthKey key(bytes);
    OPENSSL_cleanse(bytes.data(), bytes.size());
    return key;
  } catch (const std::invalid_argument& e) {
    if (!bytes.empty()) OPENSSL_cleanse(bytes.data(), bytes.size());
    throw std::invalid_argument("pre-shared key file '" + path.string() + "': " + e.what());
  }
}

std::array<std::uint8_t, kAuthTagBytes> compute_tag(std::span<const std::uint8_t> message,
                                                    const AuthKey& key) {
  std::array<std::uint8_t, EVP_MAX_MD_SIZE> full{};
  unsigned int full_len = 0;
  const auto k = key.bytes();
  const unsigned char* r = HMAC(EVP_sha256(), k.data(), static_cast<int>(k.size()), message.data(),
                                message.size(), full.data(), &full_len);
  // HMAC only fails when OpenSSL itself is broken (no SHA-256 provider): a bug, not input.
  if (r == nullptr || full_len < kAuthTagBytes)
    throw std::logic_error("HMAC-SHA256 unavailable in this OpenSSL build");
  std::array<std::uint8_t, kAuthTagBytes> tag{};
  std::copy_n(full.begin(), kAuthTagBytes, tag.begin());
  OPENSSL_cleanse(full.data(), full.size());
  return tag;
}

void append_tag(std::vector<std::uint8_t>& message, const AuthKey& key) {
  const auto tag = compute_tag(message, key);
  message.insert(message.end(), tag.begin(), tag.end());
}

std::optional<std::span<const std::uint8_t>> verify_and_strip(std::span<const std::uint8_t> tagged,
                                                              const AuthKey& key) {
  if (tagged.size() < kAuthTagBytes) return std::nullopt;
  const auto body = tagged.first(tagged.size() - kAuthTagBytes);
  const auto expected = compute_tag(body, key);
  if (CRYPTO_memcmp(expected.data(), tagged.data() + body.size(), kAuthTagBytes) != 0)
    return std::nullopt;
  return body;
}

bool ReplayWindow::test(std::uint64_t seq) const {
  const std::uint64_t i = seq % kWindow;
  return (bits_[i / 64] >> (i % 64)) & 1u;
}
void ReplayWindow::set(std::uint64_t seq) {
  const std::uint64_t i = seq % kWindow;
  bits_[i / 64] |= std::uint64_t{1} << (i % 64);
}
void ReplayWindow::clear(std::uint64_t seq) {
  const std::uint64_t i = seq % kWindow;
  bits_[i / 64] &= ~(std::uint64_t{1} << (i % 64));
}

// The bitmap is a ring indexed by seq mod kWindow (RFC 6479): advancing clears only the slots
// that fall out, so the cost is bounded by the jump, never by the window.
ReplayWindow::Verdict ReplayWindow::check_and_update(std::uint64_t seq) {
  if (!any_) {
    any_ = true;
    highest_ = seq;
    set(seq);
    return Verdict::Accepted;
  }
  if (seq > highest_) {
    const std::uint64_t jump = seq - highest_;
    if (jump >= kWindow) {
      bits_.fill(0);
    } else {
      for (std::uint64_t s = highest_ + 1; s <= seq; ++s) clear(s);
    }
    highest_ = seq;
    set(seq);
    return Verdict::Accepted;
  }
  if (highest_ - seq >= kWindow) return Verdict::TooOld;
  if (test(seq)) return Verdict::Replayed;
  set(seq);
  return Verdict::Accepted;
}

std::vector<std::uint8_t> encode_sealed(const Header& header, const Message& message,
                                        const AuthKey* key) {
  if (key == nullptr) return encode(header, message);
  Header h = header;
  h.flags |= kFlagAuth;
  std::vector<std::uint8_t> out = encode(h, message);
  append_tag(out, *key);
  return out;
}

std::vector<std::uint8_t> encode_stream_sealed(const Header& header, const Message& message,
                                               const AuthKey* key) {
  if (key == nullptr) return encode_stream(header, message);
  const std::vector<std::uint8_t> msg = encode_sealed(header, message, key);
  std::vector<std::uint8_t> out;
  out.reserve(4 + msg.size());
  detail::Writer w(out);
  w.u32(static_cast<std::uint32_t>(msg.size()));
  w.bytes(msg);
  return out;
}

AuthKey derive_session_key(const AuthKey& psk, std::uint64_t client_nonce,
                           std::uint64_t server_nonce, std::uint32_t session_id) {
  static constexpr std::string_view kLabel = "telex-session-v1";
  std::vector<std::uint8_t> input(kLabel.begin(), kLabel.end());
  detail::Writer w(input);
  w.u64(client_nonce);
  w.u64(server_nonce);
  w.u32(session_id);
  std::array<std::uint8_t, EVP_MAX_MD_SIZE> full{};
  unsigned int full_len = 0;
  const auto k = psk.bytes();
  if (HMAC(EVP_sha256(), k.data(), static_cast<int>(k.size()), input.data(), input.size(),
           full.data(), &full_len) == nullptr ||
      full_len != 32)
    throw std::logic_error("HMAC-SHA256 unavailable in this OpenSSL build");
  AuthKey out(std::span<const std::uint8_t>(full.data(), full_len));
  OPENSSL_cleanse(full.data(), full.size());
  return out;
}

void check_key_file_permissions(const std::filesystem::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0)
    throw std::runtime_error("cannot read pre-shared key file '" + path.string() +
                             "': " + std::strerror(errno));
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    throw std::invalid_argument("pre-shared key file '" + path.string() + "' has mode " + mode +
                                ": group and others must have no access (chmod 600 '" +
                                path.string() + "')");
  }
}

std::uint64_t random_u64() {
  std::uint64_t v = 0;
  if (RAND_bytes(reinterpret_cast<unsigned char*>(&v), sizeof v) != 1)
    throw std::runtime_error("the system random source failed (OpenSSL RAND_bytes)");
  return v;
}

std::uint64_t extend_seq(std::uint32_t wire_seq, std::uint64_t highest) {
  const std::uint64_t epoch = highest & ~std::uint64_t{0xFFFFFFFFu};
  const std::uint32_t low = static_cast<std::uint32_t>(highest);
  std::uint64_t candidate = epoch | wire_seq;
  const auto diff = static_cast<std::int32_t>(wire_seq - low);          // serial distance, wraps
  if (diff > 0 && wire_seq < low) candidate += std::uint64_t{1} << 32;  // wrapped forward
  if (diff < 0 && wire_seq > low && epoch != 0)
    candidate -= std::uint64_t{1} << 32;  // behind a wrap
  return candidate;
}

}  // namespace telex::proto
