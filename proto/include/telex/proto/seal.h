// SPDX-License-Identifier: MIT
// Sealed UDP datagrams: AES-256-GCM (OpenSSL EVP) under a per-direction key exported from the
// TLS session, a nonce from a 64-bit sequence number, and a sliding replay window.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace telex::proto {

inline constexpr std::size_t kSealKeyBytes = 32;    // AES-256
inline constexpr std::size_t kSealNonceBytes = 12;  // 96-bit GCM nonce (SP 800-38D 8.2.1)
inline constexpr std::size_t kSealTagBytes = 16;    // full 128-bit GCM tag
// The sealed datagram's clear header: magic "TS", 2 reserved bytes (0), the u64 sequence number
// little-endian. It is the AAD. docs/PROTOCOL.md section 7 has the layout byte by byte.
inline constexpr std::size_t kSealHeaderBytes = 12;
inline constexpr std::size_t kSealOverhead = kSealHeaderBytes + kSealTagBytes;
inline constexpr std::uint8_t kSealMagic0 = 0x54;  // 'T'
inline constexpr std::uint8_t kSealMagic1 = 0x53;  // 'S'

// ---- AES-256-GCM as a pure function (tested against the GCM spec's vectors) ----

// ciphertext || 16-byte tag of `plaintext` under key and nonce, with `aad` authenticated only.
std::vector<std::uint8_t> aes256gcm_seal(std::span<const std::uint8_t, kSealKeyBytes> key,
                                         std::span<const std::uint8_t, kSealNonceBytes> nonce,
                                         std::span<const std::uint8_t> aad,
                                         std::span<const std::uint8_t> plaintext);
// The plaintext when the tag verifies, nullopt otherwise (too short, wrong key, nonce or AAD, any
// bit changed). Nothing of an unauthentic input is returned.
std::optional<std::vector<std::uint8_t>> aes256gcm_open(
    std::span<const std::uint8_t, kSealKeyBytes> key,
    std::span<const std::uint8_t, kSealNonceBytes> nonce, std::span<const std::uint8_t> aad,
    std::span<const std::uint8_t> sealed);

// One direction's secret: the AES key and the 12-byte IV the nonces are made from. Wiped when
// dropped.
struct DirectionKey {
  std::array<std::uint8_t, kSealKeyBytes> key{};
  std::array<std::uint8_t, kSealNonceBytes> iv{};
  DirectionKey() = default;
  DirectionKey(const DirectionKey&) = default;
  DirectionKey& operator=(const DirectionKey&) = default;
  ~DirectionKey();
  // From kSealKeyBytes + kSealNonceBytes bytes (an RFC 5705 exporter's output): key, then IV.
  static DirectionKey from_bytes(std::span<const std::uint8_t, kSealKeyBytes + kSealNonceBytes> b);
};

// The nonce of sequence number `seq`: the IV XOR the sequence number as 64 bits big-endian in its
// last 8 bytes, as TLS 1.3 makes its record nonces (RFC 8446 5.3). Distinct for distinct seq.
std::array<std::uint8_t, kSealNonceBytes> seal_nonce(
    const std::array<std::uint8_t, kSealNonceBytes>& iv, std::uint64_t seq);

// Anti-replay window over one sender's 64-bit sequence numbers, as in IPsec (RFC 4303 3.4.3): the
// highest sequence seen plus a bitmap of the kWindow before it. A sequence is accepted once; one
// older than the window is rejected as too old. Call it only after the datagram authenticated,
// so forged sequence numbers cannot move the window.
class ReplayWindow {
 public:
  static constexpr std::uint64_t kWindow = 1024;
  enum class Verdict : std::uint8_t { Accepted, Replayed, TooOld };

  Verdict check_and_update(std::uint64_t seq);
  // Whether check_and_update would accept `seq`, without recording it.
  bool would_accept(std::uint64_t seq) const;
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

// Seals datagrams of one direction: sequence numbers 0, 1, 2, ... each used once.
class DatagramSealer {
 public:
  explicit DatagramSealer(const DirectionKey& key);
  ~DatagramSealer();
  DatagramSealer(const DatagramSealer&) = delete;
  DatagramSealer& operator=(const DatagramSealer&) = delete;

  // header (12) || AES-256-GCM(plain) || tag (16): plain.size() + kSealOverhead bytes. Throws
  // std::logic_error after 2^64 - 1 datagrams rather than reuse a nonce (unreachable in practice).
  std::vector<std::uint8_t> seal(std::span<const std::uint8_t> plain);
  std::uint64_t next_seq() const { return next_seq_; }

 private:
  struct Ctx;
  std::unique_ptr<Ctx> ctx_;
  std::array<std::uint8_t, kSealNonceBytes> iv_{};
  std::uint64_t next_seq_ = 0;
};

enum class OpenError : std::uint8_t {
  None,
  Truncated,   // shorter than header + tag
  BadMagic,    // not a sealed datagram (e.g. a plain fragment)
  AuthFailed,  // the tag does not verify: another key (the other direction's, a forger's) or bits
               // changed
  Replayed,    // authentic, but its sequence number was seen or is older than the window
};
std::string_view open_error_name(OpenError e);

// Opens datagrams of one direction: authenticity first, then the replay window.
class DatagramOpener {
 public:
  explicit DatagramOpener(const DirectionKey& key);
  ~DatagramOpener();
  DatagramOpener(const DatagramOpener&) = delete;
  DatagramOpener& operator=(const DatagramOpener&) = delete;

  // On None, `plain` holds the datagram's content; otherwise `plain` is cleared.
  OpenError open(std::span<const std::uint8_t> datagram, std::vector<std::uint8_t>& plain);
  const ReplayWindow& window() const { return window_; }

 private:
  struct Ctx;
  std::unique_ptr<Ctx> ctx_;
  std::array<std::uint8_t, kSealNonceBytes> iv_{};
  ReplayWindow window_;
};

}  // namespace telex::proto
