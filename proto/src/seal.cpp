// SPDX-License-Identifier: MIT
// AES-256-GCM through OpenSSL EVP, the sealed datagram (header as AAD, nonce from the sequence
// number) and the replay window.
#include "telex/proto/seal.h"

#include <openssl/crypto.h>
#include <openssl/evp.h>

#include <algorithm>
#include <stdexcept>

namespace telex::proto {
namespace {

using CtxPtr = std::unique_ptr<EVP_CIPHER_CTX, decltype(&EVP_CIPHER_CTX_free)>;

// A cipher context with the key schedule done once; each datagram then sets only its nonce.
CtxPtr make_ctx(std::span<const std::uint8_t, kSealKeyBytes> key, bool encrypt) {
  CtxPtr ctx(EVP_CIPHER_CTX_new(), &EVP_CIPHER_CTX_free);
  // These fail only when OpenSSL is out of memory or has no AES-GCM: a broken build, not input.
  if (!ctx || EVP_CipherInit_ex(ctx.get(), EVP_aes_256_gcm(), nullptr, key.data(), nullptr,
                                encrypt ? 1 : 0) != 1)
    throw std::logic_error("AES-256-GCM unavailable in this OpenSSL build");
  return ctx;
}

int len_of(std::size_t n) { return static_cast<int>(n); }

// Appends ciphertext || tag of `plain` to `out`.
void gcm_seal(EVP_CIPHER_CTX* ctx, std::span<const std::uint8_t, kSealNonceBytes> nonce,
              std::span<const std::uint8_t> aad, std::span<const std::uint8_t> plain,
              std::vector<std::uint8_t>& out) {
  const std::size_t at = out.size();
  out.resize(at + plain.size() + kSealTagBytes);
  int n = 0;
  bool ok = EVP_EncryptInit_ex(ctx, nullptr, nullptr, nullptr, nonce.data()) == 1;
  if (ok && !aad.empty())
    ok = EVP_EncryptUpdate(ctx, nullptr, &n, aad.data(), len_of(aad.size())) == 1;
  if (ok && !plain.empty())
    ok = EVP_EncryptUpdate(ctx, out.data() + at, &n, plain.data(), len_of(plain.size())) == 1;
  if (ok) ok = EVP_EncryptFinal_ex(ctx, out.data() + at + plain.size(), &n) == 1;
  if (ok)
    ok = EVP_CIPHER_CTX_ctrl(ctx, EVP_CTRL_GCM_GET_TAG, static_cast<int>(kSealTagBytes),
                             out.data() + at + plain.size()) == 1;
  if (!ok) throw std::logic_error("AES-256-GCM encryption failed inside OpenSSL");
}

// The plaintext of ciphertext || tag into `plain`; false (and `plain` cleared) when the tag fails.
bool gcm_open(EVP_CIPHER_CTX* ctx, std::span<const std::uint8_t, kSealNonceBytes> nonce,
              std::span<const std::uint8_t> aad, std::span<const std::uint8_t> sealed,
              std::vector<std::uint8_t>& plain) {
  plain.clear();
  if (sealed.size() < kSealTagBytes) return false;
  const auto ct = sealed.first(sealed.size() - kSealTagBytes);
  std::array<std::uint8_t, kSealTagBytes> tag{};
  std::copy_n(sealed.data() + ct.size(), kSealTagBytes, tag.begin());
  plain.resize(ct.size());
  int n = 0;
  bool ok = EVP_DecryptInit_ex(ctx, nullptr, nullptr, nullptr, nonce.data()) == 1;
  if (ok && !aad.empty())
    ok = EVP_DecryptUpdate(ctx, nullptr, &n, aad.data(), len_of(aad.size())) == 1;
  if (ok && !ct.empty())
    ok = EVP_DecryptUpdate(ctx, plain.data(), &n, ct.data(), len_of(ct.size())) == 1;
  if (ok)
    ok = EVP_CIPHER_CTX_ctrl(ctx, EVP_CTRL_GCM_SET_TAG, static_cast<int>(kSealTagBytes),
                             tag.data()) == 1;
  // The tag is compared inside DecryptFinal (constant time); only then is the plaintext real.
  if (ok) ok = EVP_DecryptFinal_ex(ctx, plain.data() + plain.size(), &n) == 1;
  if (!ok) {
    if (!plain.empty()) OPENSSL_cleanse(plain.data(), plain.size());
    plain.clear();
  }
  return ok;
}

void put_u64le(std::uint8_t* p, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
std::uint64_t get_u64le(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

}  // namespace

std::vector<std::uint8_t> aes256gcm_seal(std::span<const std::uint8_t, kSealKeyBytes> key,
                                         std::span<const std::uint8_t, kSealNonceBytes> nonce,
                                         std::span<const std::uint8_t> aad,
                                         std::span<const std::uint8_t> plaintext) {
  auto ctx = make_ctx(key, true);
  std::vector<std::uint8_t> out;
  gcm_seal(ctx.get(), nonce, aad, plaintext, out);
  return out;
}

std::optional<std::vector<std::uint8_t>> aes256gcm_open(
    std::span<const std::uint8_t, kSealKeyBytes> key,
    std::span<const std::uint8_t, kSealNonceBytes> nonce, std::span<const std::uint8_t> aad,
    std::span<const std::uint8_t> sealed) {
  auto ctx = make_ctx(key, false);
  std::vector<std::uint8_t> plain;
  if (!gcm_open(ctx.get(), nonce, aad, sealed, plain)) return std::nullopt;
  return plain;
}

DirectionKey::~DirectionKey() {
  OPENSSL_cleanse(key.data(), key.size());
  OPENSSL_cleanse(iv.data(), iv.size());
}

DirectionKey DirectionKey::from_bytes(
    std::span<const std::uint8_t, kSealKeyBytes + kSealNonceBytes> b) {
  DirectionKey k;
  std::copy_n(b.data(), kSealKeyBytes, k.key.begin());
  std::copy_n(b.data() + kSealKeyBytes, kSealNonceBytes, k.iv.begin());
  return k;
}

std::array<std::uint8_t, kSealNonceBytes> seal_nonce(
    const std::array<std::uint8_t, kSealNonceBytes>& iv, std::uint64_t seq) {
  std::array<std::uint8_t, kSealNonceBytes> n = iv;
  for (int i = 0; i < 8; ++i)
    n[kSealNonceBytes - 1 - i] ^= static_cast<std::uint8_t>(seq >> (8 * i));
  return n;
}

// ---- replay window ----

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

bool ReplayWindow::would_accept(std::uint64_t seq) const {
  if (!any_ || seq > highest_) return true;
  if (highest_ - seq >= kWindow) return false;
  return !test(seq);
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

// ---- sealer and opener ----

struct DatagramSealer::Ctx {
  CtxPtr c;
};
struct DatagramOpener::Ctx {
  CtxPtr c;
};

DatagramSealer::DatagramSealer(const DirectionKey& key)
    : ctx_(std::make_unique<Ctx>(Ctx{make_ctx(key.key, true)})), iv_(key.iv) {}
DatagramSealer::~DatagramSealer() { OPENSSL_cleanse(iv_.data(), iv_.size()); }

std::vector<std::uint8_t> DatagramSealer::seal(std::span<const std::uint8_t> plain) {
  if (next_seq_ == ~std::uint64_t{0})
    throw std::logic_error("sealed datagram sequence numbers exhausted: a nonce would repeat");
  const std::uint64_t seq = next_seq_++;
  std::vector<std::uint8_t> out;
  out.reserve(kSealOverhead + plain.size());
  out.resize(kSealHeaderBytes);
  out[0] = kSealMagic0;
  out[1] = kSealMagic1;
  out[2] = out[3] = 0;
  put_u64le(out.data() + 4, seq);
  const std::array<std::uint8_t, kSealHeaderBytes> aad = [&] {
    std::array<std::uint8_t, kSealHeaderBytes> a{};
    std::copy_n(out.begin(), kSealHeaderBytes, a.begin());
    return a;
  }();
  gcm_seal(ctx_->c.get(), seal_nonce(iv_, seq), aad, plain, out);
  return out;
}

DatagramOpener::DatagramOpener(const DirectionKey& key)
    : ctx_(std::make_unique<Ctx>(Ctx{make_ctx(key.key, false)})), iv_(key.iv) {}
DatagramOpener::~DatagramOpener() { OPENSSL_cleanse(iv_.data(), iv_.size()); }

OpenError DatagramOpener::open(std::span<const std::uint8_t> datagram,
                               std::vector<std::uint8_t>& plain) {
  plain.clear();
  if (datagram.size() < kSealOverhead) return OpenError::Truncated;
  if (datagram[0] != kSealMagic0 || datagram[1] != kSealMagic1) return OpenError::BadMagic;
  const std::uint64_t seq = get_u64le(datagram.data() + 4);
  // A number the window already refuses is not worth a decryption (a replay flood costs less).
  if (!window_.would_accept(seq)) return OpenError::Replayed;
  const auto aad = datagram.first(kSealHeaderBytes);
  if (!gcm_open(ctx_->c.get(), seal_nonce(iv_, seq), aad, datagram.subspan(kSealHeaderBytes),
                plain))
    return OpenError::AuthFailed;
  if (window_.check_and_update(seq) != ReplayWindow::Verdict::Accepted) {
    plain.clear();
    return OpenError::Replayed;
  }
  return OpenError::None;
}

std::string_view open_error_name(OpenError e) {
  switch (e) {
    case OpenError::None:
      return "none";
    case OpenError::Truncated:
      return "truncated";
    case OpenError::BadMagic:
      return "bad-magic";
    case OpenError::AuthFailed:
      return "auth-failed";
    case OpenError::Replayed:
      break;
  }
  return "replayed";
}

}  // namespace telex::proto
