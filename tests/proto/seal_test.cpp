// SPDX-License-Identifier: MIT
// The datagram seal: AES-256-GCM against the GCM spec's test vectors, the sealed layout, nonces,
// tampering, the other direction's key (reflection), replays, and the key file's permissions.
#include "telex/proto/seal.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <string>

#include "process.h"
#include "telex/proto/auth.h"

namespace telex::proto {
namespace {

std::vector<std::uint8_t> hex(std::string_view h) {
  std::vector<std::uint8_t> out;
  for (std::size_t i = 0; i + 1 < h.size(); i += 2)
    out.push_back(static_cast<std::uint8_t>(std::stoi(std::string(h.substr(i, 2)), nullptr, 16)));
  return out;
}

struct GcmVector {
  const char* name;
  const char* key;
  const char* iv;
  const char* aad;
  const char* plain;
  const char* cipher;
  const char* tag;
};

// McGrew & Viega, "The Galois/Counter Mode of Operation (GCM)", appendix B, the AES-256 cases
// (13-16); NIST's GCM test vectors repeat them.
const GcmVector kVectors[] = {
    {"TestCase13", "0000000000000000000000000000000000000000000000000000000000000000",
     "000000000000000000000000", "", "", "", "530f8afbc74536b9a963b4f1c4cb738b"},
    {"TestCase14", "0000000000000000000000000000000000000000000000000000000000000000",
     "000000000000000000000000", "", "00000000000000000000000000000000",
     "cea7403d4d606b6e074ec5d3baf39d18", "d0d1c8a799996bf0265b98b5d48ab919"},
    {"TestCase15", "feffe9928665731c6d6a8f9467308308feffe9928665731c6d6a8f9467308308",
     "cafebabefacedbaddecaf888", "",
     "d9313225f88406e5a55909c5aff5269a86a7a9531534f7da2e4c303d8a318a721c3c0c95956809532fcf0e2449a6b"
     "5"
     "25b16aedf5aa0de657ba637b391aafd255",
     "522dc1f099567d07f47f37a32a84427d643a8cdcbfe5c0c97598a2bd2555d1aa8cb08e48590dbb3da7b08b105682"
     "8838c5f61e6393ba7a0abcc9f662898015ad",
     "b094dac5d93471bdec1a502270e3cc6c"},
    {"TestCase16", "feffe9928665731c6d6a8f9467308308feffe9928665731c6d6a8f9467308308",
     "cafebabefacedbaddecaf888", "feedfacedeadbeeffeedfacedeadbeefabaddad2",
     "d9313225f88406e5a55909c5aff5269a86a7a9531534f7da2e4c303d8a318a721c3c0c95956809532fcf0e2449a6b"
     "5"
     "25b16aedf5aa0de657ba637b39",
     "522dc1f099567d07f47f37a32a84427d643a8cdcbfe5c0c97598a2bd2555d1aa8cb08e48590dbb3da7b08b105682"
     "8838c5f61e6393ba7a0abcc9f662",
     "76fc6ece0f4e1768cddf8853bb2d551b"},
};

TEST(Aes256Gcm, MatchesTheGcmSpecVectors) {
  for (const auto& v : kVectors) {
    SCOPED_TRACE(v.name);
    const auto key = hex(v.key), iv = hex(v.iv), aad = hex(v.aad), plain = hex(v.plain);
    std::vector<std::uint8_t> expected = hex(v.cipher);
    const auto tag = hex(v.tag);
    expected.insert(expected.end(), tag.begin(), tag.end());
    const std::span<const std::uint8_t, kSealKeyBytes> k(key.data(), kSealKeyBytes);
    const std::span<const std::uint8_t, kSealNonceBytes> n(iv.data(), kSealNonceBytes);
    EXPECT_EQ(aes256gcm_seal(k, n, aad, plain), expected);
    const auto opened = aes256gcm_open(k, n, aad, expected);
    ASSERT_TRUE(opened.has_value());
    EXPECT_EQ(*opened, plain);
  }
}

TEST(Aes256Gcm, AnyChangedBitOfCiphertextTagOrAadFails) {
  const auto& v = kVectors[3];
  const auto key = hex(v.key), iv = hex(v.iv), aad = hex(v.aad);
  const std::span<const std::uint8_t, kSealKeyBytes> k(key.data(), kSealKeyBytes);
  const std::span<const std::uint8_t, kSealNonceBytes> n(iv.data(), kSealNonceBytes);
  const auto sealed = aes256gcm_seal(k, n, aad, hex(v.plain));
  for (std::size_t i = 0; i < sealed.size(); ++i) {
    auto bad = sealed;
    bad[i] ^= static_cast<std::uint8_t>(1u << (i % 8));
    EXPECT_FALSE(aes256gcm_open(k, n, aad, bad).has_value()) << "byte " << i;
  }
  for (std::size_t i = 0; i < aad.size(); ++i) {
    auto bad_aad = aad;
    bad_aad[i] ^= 0x80;
    EXPECT_FALSE(aes256gcm_open(k, n, bad_aad, sealed).has_value()) << "aad byte " << i;
  }
  auto other_iv = iv;
  other_iv[11] ^= 1;
  EXPECT_FALSE(aes256gcm_open(
                   k,
                   std::span<const std::uint8_t, kSealNonceBytes>(other_iv.data(), kSealNonceBytes),
                   aad, sealed)
                   .has_value());
  EXPECT_FALSE(aes256gcm_open(k, n, aad, std::span(sealed).first(15)).has_value());
}

DirectionKey key_filled(std::uint8_t k, std::uint8_t iv) {
  DirectionKey d;
  d.key.fill(k);
  d.iv.fill(iv);
  return d;
}

TEST(SealNonce, IvXorBigEndianSequenceAsTls13) {
  std::array<std::uint8_t, kSealNonceBytes> iv{};
  for (std::size_t i = 0; i < iv.size(); ++i) iv[i] = static_cast<std::uint8_t>(0xA0 + i);
  const auto n = seal_nonce(iv, 0x0102030405060708ull);
  const std::array<std::uint8_t, kSealNonceBytes> expected = {
      0xA0,        0xA1,        0xA2,        0xA3,        0xA4 ^ 0x01, 0xA5 ^ 0x02,
      0xA6 ^ 0x03, 0xA7 ^ 0x04, 0xA8 ^ 0x05, 0xA9 ^ 0x06, 0xAA ^ 0x07, 0xAB ^ 0x08};
  EXPECT_EQ(n, expected);
  std::set<std::array<std::uint8_t, kSealNonceBytes>> seen;
  for (std::uint64_t s = 0; s < 5000; ++s) seen.insert(seal_nonce(iv, s * 0x10001ull));
  EXPECT_EQ(seen.size(), 5000u);
}

TEST(DatagramSeal, LayoutIsHeaderCiphertextTagAndOpensOnceInOrderOrNot) {
  const auto k = key_filled(0x11, 0x22);
  DatagramSealer sealer(k);
  DatagramOpener opener(k);
  std::vector<std::uint8_t> plain(1400);
  for (std::size_t i = 0; i < plain.size(); ++i) plain[i] = static_cast<std::uint8_t>(i);
  std::vector<std::vector<std::uint8_t>> sealed;
  for (int i = 0; i < 4; ++i) sealed.push_back(sealer.seal(plain));
  const auto& d = sealed[2];
  ASSERT_EQ(d.size(), plain.size() + kSealOverhead);
  EXPECT_EQ(d[0], 'T');
  EXPECT_EQ(d[1], 'S');
  EXPECT_EQ(d[2], 0);
  EXPECT_EQ(d[3], 0);
  EXPECT_EQ(d[4], 2);  // sequence number 2, little-endian
  for (int i = 5; i < 12; ++i) EXPECT_EQ(d[static_cast<std::size_t>(i)], 0);
  // The content is the GCM encryption under the nonce of seq 2 with the header as AAD.
  const auto nonce = seal_nonce(k.iv, 2);
  EXPECT_EQ(std::vector<std::uint8_t>(d.begin() + kSealHeaderBytes, d.end()),
            aes256gcm_seal(k.key, nonce, std::span(d).first(kSealHeaderBytes), plain));

  std::vector<std::uint8_t> out;
  EXPECT_EQ(opener.open(sealed[1], out), OpenError::None);
  EXPECT_EQ(out, plain);
  EXPECT_EQ(opener.open(sealed[3], out), OpenError::None);
  EXPECT_EQ(opener.open(sealed[0], out), OpenError::None);  // reordered within the window
  EXPECT_EQ(opener.open(sealed[3], out), OpenError::Replayed);
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(opener.open(sealed[2], out), OpenError::None);
}

TEST(DatagramSeal, TamperedHeaderOrBodyAndPlainFragmentsAreRefused) {
  const auto k = key_filled(0x31, 0x32);
  DatagramSealer sealer(k);
  const std::vector<std::uint8_t> plain(300, 0xAB);
  const auto d = sealer.seal(plain);
  for (std::size_t i = 2; i < d.size(); ++i) {  // bytes 0-1 are the magic
    DatagramOpener opener(k);
    auto bad = d;
    bad[i] ^= 0x04;
    std::vector<std::uint8_t> out;
    const auto e = opener.open(bad, out);
    EXPECT_EQ(e, OpenError::AuthFailed) << "byte " << i;
    EXPECT_TRUE(out.empty());
    // The forged copy did not move the window: the real datagram still opens.
    EXPECT_EQ(opener.open(d, out), OpenError::None) << "byte " << i;
  }
  DatagramOpener opener(k);
  std::vector<std::uint8_t> out;
  std::vector<std::uint8_t> fragment = {'T', 'F', 0, 0, 1, 0, 0, 0};
  fragment.resize(40, 0x55);
  EXPECT_EQ(opener.open(fragment, out), OpenError::BadMagic);
  EXPECT_EQ(opener.open(std::span(d).first(kSealOverhead - 1), out), OpenError::Truncated);
}

TEST(DatagramSeal, TheOtherDirectionsKeyDoesNotOpenAReflectedDatagram) {
  const auto remote_to_station = key_filled(0x41, 0x42);
  const auto station_to_remote = key_filled(0x51, 0x52);
  DatagramSealer remote_tx(remote_to_station);
  DatagramOpener remote_rx(station_to_remote);
  DatagramOpener station_rx(remote_to_station);
  const auto d = remote_tx.seal(std::vector<std::uint8_t>(64, 7));
  std::vector<std::uint8_t> out;
  EXPECT_EQ(remote_rx.open(d, out), OpenError::AuthFailed);  // reflected to its sender
  EXPECT_EQ(station_rx.open(d, out), OpenError::None);       // where it was meant to go
}

TEST(DatagramSeal, NoRepeatedBlockInSealedRepetitiveData) {
  // Depth tiles and JPEGs repeat themselves; GCM's counter mode must not show it.
  DatagramSealer sealer(key_filled(0x61, 0x62));
  const auto d = sealer.seal(std::vector<std::uint8_t>(1400, 0));
  std::set<std::vector<std::uint8_t>> blocks;
  for (std::size_t i = kSealHeaderBytes; i + 16 <= d.size(); i += 16)
    EXPECT_TRUE(blocks
                    .insert({d.begin() + static_cast<std::ptrdiff_t>(i),
                             d.begin() + static_cast<std::ptrdiff_t>(i + 16)})
                    .second);
}

TEST(DatagramSeal, RandomForgeriesNeverOpen) {
  DatagramOpener opener(key_filled(0x71, 0x72));
  std::mt19937 rng(42);
  std::vector<std::uint8_t> out;
  int opened = 0;
  for (int i = 0; i < 2000; ++i) {
    std::vector<std::uint8_t> d(kSealOverhead + rng() % 200);
    for (auto& b : d) b = static_cast<std::uint8_t>(rng());
    d[0] = 'T';
    d[1] = 'S';
    opened += opener.open(d, out) == OpenError::None;
  }
  EXPECT_EQ(opened, 0);
  EXPECT_TRUE(opener.window().empty());
}

TEST(AuthKeyFile, PermissionsOpenToOthersAreRefusedWithTheFix) {
  const auto dir = ::telex::test::scratch_dir("psk_perm");
  std::filesystem::create_directories(dir);
  const auto path = dir / "key";
  { std::ofstream(path, std::ios::binary) << std::string(32, 'k'); }
  std::filesystem::permissions(path, std::filesystem::perms::owner_read |
                                         std::filesystem::perms::owner_write |
                                         std::filesystem::perms::group_read);
  try {
    check_key_file_permissions(path);
    ADD_FAILURE() << "mode 0640 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("chmod 600"), std::string::npos) << e.what();
  }
  std::filesystem::permissions(path, std::filesystem::perms::owner_read);
  EXPECT_NO_THROW(check_key_file_permissions(path));
  EXPECT_THROW(check_key_file_permissions(dir / "absent"), std::runtime_error);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace telex::proto
