// SPDX-License-Identifier: MIT
// The TLS contexts in memory (a BIO pair, no socket): PSK with (EC)DHE only, the exporter's keys
// per direction, a key mismatch named on both sides, mixed flags refused, the loopback rule.
#include "telex/proto/tls.h"

#include <gtest/gtest.h>
#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/ssl.h>

#include <filesystem>
#include <memory>
#include <string>

#include "process.h"
#include "telex/proto/certs.h"

namespace telex::proto {
namespace {

AuthKey key_of(std::uint8_t fill) { return AuthKey(std::vector<std::uint8_t>(32, fill)); }

struct Pair {
  std::unique_ptr<SSL_CTX, decltype(&SSL_CTX_free)> server_ctx{nullptr, &SSL_CTX_free};
  std::unique_ptr<SSL_CTX, decltype(&SSL_CTX_free)> client_ctx{nullptr, &SSL_CTX_free};
  std::unique_ptr<SSL, decltype(&SSL_free)> server{nullptr, &SSL_free};
  std::unique_ptr<SSL, decltype(&SSL_free)> client{nullptr, &SSL_free};
  unsigned long server_error = 0, client_error = 0;

  Pair(const TlsConfig& s, const TlsConfig& c) {
    server_ctx.reset(make_tls_context(s, TlsRole::Server));
    client_ctx.reset(make_tls_context(c, TlsRole::Client));
    server.reset(SSL_new(server_ctx.get()));
    client.reset(SSL_new(client_ctx.get()));
    BIO* sb = nullptr;
    BIO* cb = nullptr;
    BIO_new_bio_pair(&sb, 0, &cb, 0);
    SSL_set_bio(server.get(), sb, sb);
    SSL_set_bio(client.get(), cb, cb);
    SSL_set_accept_state(server.get());
    SSL_set_connect_state(client.get());
  }

  // Steps both ends until both finish or one fails; true when both finished.
  bool handshake() {
    bool s_done = false, c_done = false;
    for (int i = 0; i < 50 && !(s_done && c_done); ++i) {
      if (!c_done && client_error == 0) {
        ERR_clear_error();
        const int r = SSL_do_handshake(client.get());
        if (r == 1)
          c_done = true;
        else if (SSL_get_error(client.get(), r) == SSL_ERROR_SSL)
          client_error = ERR_peek_error();
      }
      if (!s_done && server_error == 0) {
        ERR_clear_error();
        const int r = SSL_do_handshake(server.get());
        if (r == 1)
          s_done = true;
        else if (SSL_get_error(server.get(), r) == SSL_ERROR_SSL)
          server_error = ERR_peek_error();
      }
      if (client_error != 0 && server_error != 0) break;
    }
    return s_done && c_done;
  }
};

TlsConfig psk_config(std::uint8_t fill) {
  TlsConfig c;
  c.psk = key_of(fill);
  return c;
}

TEST(Tls, PskHandshakeUsesEcdheAndExportsCrossedKeysPerDirection) {
  Pair p(psk_config(0x42), psk_config(0x42));
  ASSERT_TRUE(p.handshake()) << p.server_error << " " << p.client_error;
  EXPECT_EQ(SSL_version(p.server.get()), TLS1_3_VERSION);
  EXPECT_STREQ(SSL_get_cipher_name(p.server.get()), "TLS_AES_256_GCM_SHA384");
  // psk_dhe_ke: a key exchange group was negotiated (forward secrecy), not psk_ke.
  EXPECT_NE(SSL_get_negotiated_group(p.server.get()), 0);
  EXPECT_EQ(SSL_CTX_get_options(p.server_ctx.get()) & SSL_OP_ALLOW_NO_DHE_KEX, 0u);
  EXPECT_TRUE(SSL_session_reused(p.server.get()));  // the external PSK was the one used
  const auto s = export_link_keys(p.server.get(), TlsRole::Server);
  const auto c = export_link_keys(p.client.get(), TlsRole::Client);
  EXPECT_EQ(s.tx.key, c.rx.key);
  EXPECT_EQ(s.tx.iv, c.rx.iv);
  EXPECT_EQ(s.rx.key, c.tx.key);
  EXPECT_NE(s.tx.key, s.rx.key);  // one key per direction
  // Each connection has its own keys (fresh (EC)DHE and randoms), even under one PSK.
  Pair q(psk_config(0x42), psk_config(0x42));
  ASSERT_TRUE(q.handshake());
  EXPECT_NE(export_link_keys(q.server.get(), TlsRole::Server).tx.key, s.tx.key);
}

TEST(Tls, DifferentKeysFailAndBothSidesNameTheMismatch) {
  Pair p(psk_config(0x42), psk_config(0x43));
  ASSERT_FALSE(p.handshake());
  ASSERT_NE(p.server_error, 0u);
  ASSERT_NE(p.client_error, 0u);
  const auto server_says =
      explain_tls_failure(p.server_error, "x", TlsRole::Server, psk_config(0x42));
  const auto client_says =
      explain_tls_failure(p.client_error, "x", TlsRole::Client, psk_config(0x43));
  EXPECT_NE(server_says.find("key mismatch"), std::string::npos) << server_says;
  EXPECT_NE(client_says.find("key mismatch"), std::string::npos) << client_says;
  EXPECT_NE(client_says.find("--psk"), std::string::npos) << client_says;
}

TEST(Tls, MixedOrIncompleteFlagsAreRefused) {
  EXPECT_THROW(validate_tls_flags(false, "c.pem", "", ""), std::invalid_argument);
  EXPECT_THROW(validate_tls_flags(true, "c.pem", "k.pem", "ca.pem"), std::invalid_argument);
  EXPECT_NO_THROW(validate_tls_flags(true, "", "", ""));
  EXPECT_NO_THROW(validate_tls_flags(false, "c.pem", "k.pem", "ca.pem"));
  TlsConfig missing;
  missing.cert = "/nonexistent/telex-cert.pem";
  missing.key = "/nonexistent/telex-key.pem";
  missing.ca = "/nonexistent/telex-ca.pem";
  try {
    SSL_CTX_free(make_tls_context(missing, TlsRole::Server));
    ADD_FAILURE() << "missing certificate accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("telex-cert.pem"), std::string::npos) << e.what();
  }
}

TEST(Tls, LoopbackRule) {
  EXPECT_TRUE(is_loopback_host("127.0.0.1"));
  EXPECT_TRUE(is_loopback_host("127.3.4.5"));
  EXPECT_TRUE(is_loopback_host("::1"));
  EXPECT_TRUE(is_loopback_host("localhost"));
  EXPECT_FALSE(is_loopback_host("0.0.0.0"));
  EXPECT_FALSE(is_loopback_host("10.0.0.1"));
  EXPECT_FALSE(is_loopback_host("::"));
  EXPECT_FALSE(is_loopback_host("no-such-host.invalid"));
  const auto msg = insecure_refusal("--listen", "0.0.0.0:7300");
  EXPECT_NE(msg.find("--insecure"), std::string::npos);
  EXPECT_NE(msg.find("robot head"), std::string::npos);
}

}  // namespace
}  // namespace telex::proto

namespace telex::proto {
namespace {

// `telex certs`: the CA it makes verifies both daemons' certificates in a mutual handshake, and
// the key usages hold: the station's certificate (clientAuth) does not serve as the remote's.
TEST(LinkCertificates, MakeAWorkingPairWithTheRightKeyUsages) {
  const auto dir = ::telex::test::scratch_dir("link_certs");
  const auto c = make_link_certificates(dir / "certs", 2, {"robot.local", "192.0.2.7"});
  const auto perms = std::filesystem::status(c.remote_key).permissions();
  EXPECT_EQ(perms & (std::filesystem::perms::group_all | std::filesystem::perms::others_all),
            std::filesystem::perms::none);
  TlsConfig remote{std::nullopt, c.remote_cert, c.remote_key, c.ca_cert};
  TlsConfig station{std::nullopt, c.station_cert, c.station_key, c.ca_cert};
  Pair ok(remote, station);
  ASSERT_TRUE(ok.handshake()) << ok.server_error << " " << ok.client_error;
  EXPECT_FALSE(unauthenticated_session(ok.client.get(), TlsRole::Client, station).has_value());
  EXPECT_FALSE(unauthenticated_session(ok.server.get(), TlsRole::Server, remote).has_value());
  // The roles swapped: each certificate's extended key usage refuses it.
  Pair swapped(station, remote);
  EXPECT_FALSE(swapped.handshake());
  // Never over existing files.
  EXPECT_THROW(make_link_certificates(dir / "certs", 2, {}), std::runtime_error);
}

// --psk: a peer that shows a certificate, and a handshake without the PSK, are refused.
TEST(Tls, PskModeRefusesACertificateOnlyServer) {
  const auto dir = ::telex::test::scratch_dir("psk_vs_cert");
  const auto c = make_link_certificates(dir / "certs", 2, {});
  TlsConfig impostor{std::nullopt, c.remote_cert, c.remote_key, c.ca_cert};
  Pair p(impostor, psk_config(0x42));
  EXPECT_FALSE(p.handshake());
  ASSERT_NE(p.client_error, 0u);
  const auto says = explain_tls_failure(p.client_error, "x", TlsRole::Client, psk_config(0x42));
  EXPECT_NE(says.find("certificate, not the shared key"), std::string::npos) << says;
}

}  // namespace
}  // namespace telex::proto
