// SPDX-License-Identifier: MIT
// TLS 1.3 for the TCP connection (OpenSSL): external pre-shared key with (EC)DHE or certificates,
// the RFC 5705 exporter that keys the sealed datagrams, and what a failed handshake means.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "telex/proto/auth.h"
#include "telex/proto/seal.h"

// OpenSSL's types, so this header does not pull in OpenSSL's.
typedef struct ssl_ctx_st SSL_CTX;
typedef struct ssl_st SSL;

namespace telex::proto {

enum class TlsRole : std::uint8_t { Server, Client };  // the remote serves, the station connects

// How the link is protected. Neither a key nor certificates: plain TCP and UDP (allowed on
// loopback, or off it with --insecure; the daemons decide).
struct TlsConfig {
  std::optional<AuthKey> psk;  // --psk FILE
  std::filesystem::path cert;  // --cert FILE: this daemon's certificate chain (PEM)
  std::filesystem::path key;   // --key FILE: its private key (PEM)
  std::filesystem::path ca;    // --ca FILE: the CA the peer's certificate must chain to (PEM)
  bool certificates() const { return !cert.empty(); }
  bool enabled() const { return psk.has_value() || certificates(); }
  // "--psk" or "certificates", for log lines.
  std::string describe() const;
};

// Throws std::invalid_argument with the flags to fix when the combination is incomplete or mixed:
// --cert, --key and --ca go together; --psk and certificates are exclusive.
void validate_tls_flags(bool has_psk, const std::filesystem::path& cert,
                        const std::filesystem::path& key, const std::filesystem::path& ca);

// A new SSL_CTX for `role`: TLS 1.3 only, the one suite TLS_AES_256_GCM_SHA384, and
//  - with a key: external PSK (identity kPskIdentity) with (EC)DHE only (psk_dhe_ke:
//    SSL_OP_ALLOW_NO_DHE_KEX stays off), so every session has forward secrecy;
//  - with certificates: this side's chain and key, and the peer's certificate required and
//    verified against the CA, both ways.
// The caller owns the result (SSL_CTX_free, or hand it to asio::ssl::context). Throws
// std::invalid_argument naming the file when a certificate, key or CA cannot be loaded or the key
// does not match the certificate.
SSL_CTX* make_tls_context(const TlsConfig& config, TlsRole role);

inline constexpr const char* kPskIdentity = "telex-psk-v4";
// The exporter labels (RFC 5705 / RFC 8446 7.5), one per direction.
inline constexpr const char* kExporterRemoteToStation = "EXPORTER-telex remote->station";
inline constexpr const char* kExporterStationToRemote = "EXPORTER-telex station->remote";

// The datagram keys of one session, after the handshake: `tx` seals what this side sends, `rx`
// opens what it receives. Distinct per direction, so a datagram reflected to its sender fails.
struct LinkKeys {
  DirectionKey tx;
  DirectionKey rx;
};
// Throws std::runtime_error when the session cannot export (no TLS 1.3 session yet).
LinkKeys export_link_keys(SSL* ssl, TlsRole role);

// Checked after every handshake, on both sides, before a byte of the session is sent: with --psk
// the session must have been made from the PSK (OpenSSL reports an external PSK as a resumed
// session) and no certificate shown; with certificates the peer's must have verified. Returns
// what is wrong, for the log and the auth_failed count; nullopt when the peer is authenticated.
std::optional<std::string> unauthenticated_session(SSL* ssl, TlsRole role, const TlsConfig& config);

// What a failed handshake says to the operator of `role`, from OpenSSL's error code (the value of
// an asio ssl error_code): names a key mismatch, a peer without TLS, a certificate the CA does not
// vouch for; otherwise the OpenSSL text.
std::string explain_tls_failure(unsigned long openssl_error, const std::string& openssl_text,
                                TlsRole role, const TlsConfig& config);
// True when the failure is the peer speaking plain TCP (the first bytes are no TLS record).
bool tls_failure_is_plain_peer(unsigned long openssl_error);

// The numeric addresses HOST names (an address literal, "[v6]" or a name), each once, resolved
// now. Throws std::invalid_argument naming HOST when it does not resolve. A daemon resolves once
// at start: the addresses it checks (loopback or not) are the ones it then uses.
std::vector<std::string> resolve_host(const std::string& host);
// True for a numeric loopback address (127.0.0.0/8, ::1, ::ffff:127.x.y.z).
bool is_loopback_address(const std::string& address);
// True when every address HOST names is a loopback address (127.0.0.0/8, ::1, "localhost").
// A name that does not resolve counts as not loopback.
bool is_loopback_host(const std::string& host);

// The sentence both daemons print when a non-loopback address has no key or certificates.
std::string insecure_refusal(const std::string& flag, const std::string& address);
// The warning printed at start and every minute with --insecure.
std::string insecure_warning();

}  // namespace telex::proto
