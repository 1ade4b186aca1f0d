// SPDX-License-Identifier: MIT
// OpenSSL TLS 1.3 contexts (external PSK with (EC)DHE, or mutual certificates), the RFC 5705
// exporter keys of the sealed datagrams, handshake failures in words, the loopback rule.
#include "telex/proto/tls.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <openssl/core_names.h>
#include <openssl/crypto.h>
#include <openssl/err.h>
#include <openssl/kdf.h>
#include <openssl/ssl.h>
#include <sys/socket.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <memory>
#include <optional>
#include <stdexcept>
#include <vector>

namespace telex::proto {
namespace {

// TLS_AES_256_GCM_SHA384 (RFC 8446 B.4).
constexpr unsigned char kSuiteId[2] = {0x13, 0x02};
constexpr std::size_t kPskBytes = 48;  // one SHA-384 output

// The TLS PSK of a key file: HKDF-SHA384 (RFC 5869) of its bytes, so key files of any allowed
// length (32..1024 bytes, auth.h kMinKeyBytes) give an external PSK of the suite's hash length.
struct Psk {
  std::array<unsigned char, kPskBytes> bytes{};
  ~Psk() { OPENSSL_cleanse(bytes.data(), bytes.size()); }
};

std::string ssl_errors() {
  std::string out;
  while (const unsigned long e = ERR_get_error()) {
    char buf[256];
    ERR_error_string_n(e, buf, sizeof buf);
    if (!out.empty()) out += "; ";
    out += buf;
  }
  return out.empty() ? std::string("unknown OpenSSL error") : out;
}

Psk derive_psk(const AuthKey& key) {
  Psk psk;
  static constexpr char kSalt[] = "telex external psk v4";
  std::unique_ptr<EVP_KDF, decltype(&EVP_KDF_free)> kdf(EVP_KDF_fetch(nullptr, "HKDF", nullptr),
                                                        &EVP_KDF_free);
  std::unique_ptr<EVP_KDF_CTX, decltype(&EVP_KDF_CTX_free)> ctx(
      kdf ? EVP_KDF_CTX_new(kdf.get()) : nullptr, &EVP_KDF_CTX_free);
  const auto k = key.bytes();
  char digest[] = "SHA384";
  OSSL_PARAM params[] = {OSSL_PARAM_construct_utf8_string(OSSL_KDF_PARAM_DIGEST, digest, 0),
                         OSSL_PARAM_construct_octet_string(
                             OSSL_KDF_PARAM_KEY, const_cast<std::uint8_t*>(k.data()), k.size()),
                         OSSL_PARAM_construct_octet_string(
                             OSSL_KDF_PARAM_SALT, const_cast<char*>(kSalt), sizeof kSalt - 1),
                         OSSL_PARAM_construct_end()};
  if (!ctx || EVP_KDF_derive(ctx.get(), psk.bytes.data(), psk.bytes.size(), params) != 1)
    throw std::logic_error("HKDF-SHA384 unavailable in this OpenSSL build: " + ssl_errors());
  return psk;
}

void free_psk(void*, void* ptr, CRYPTO_EX_DATA*, int, long, void*) {
  delete static_cast<Psk*>(ptr);
}

int psk_index() {
  static const int index = SSL_CTX_get_ex_new_index(0, nullptr, nullptr, nullptr, &free_psk);
  return index;
}

// A resumption-less session that carries the external PSK (OpenSSL 3's way to offer one).
SSL_SESSION* psk_session(SSL* ssl) {
  const auto* psk = static_cast<const Psk*>(SSL_CTX_get_ex_data(SSL_get_SSL_CTX(ssl), psk_index()));
  const SSL_CIPHER* cipher = SSL_CIPHER_find(ssl, kSuiteId);
  if (psk == nullptr || cipher == nullptr) return nullptr;
  SSL_SESSION* s = SSL_SESSION_new();
  if (s == nullptr) return nullptr;
  if (SSL_SESSION_set1_master_key(s, psk->bytes.data(), psk->bytes.size()) != 1 ||
      SSL_SESSION_set_cipher(s, cipher) != 1 ||
      SSL_SESSION_set_protocol_version(s, TLS1_3_VERSION) != 1) {
    SSL_SESSION_free(s);
    return nullptr;
  }
  return s;
}

int client_psk(SSL* ssl, const EVP_MD* md, const unsigned char** id, std::size_t* idlen,
               SSL_SESSION** sess) {
  *sess = nullptr;
  *id = nullptr;
  *idlen = 0;
  const SSL_CIPHER* cipher = SSL_CIPHER_find(ssl, kSuiteId);
  // After a HelloRetryRequest the suite's hash is fixed: offer the PSK only when it matches.
  if (cipher == nullptr || (md != nullptr && md != SSL_CIPHER_get_handshake_digest(cipher)))
    return 1;
  SSL_SESSION* s = psk_session(ssl);
  if (s == nullptr) return 0;
  *sess = s;
  *id = reinterpret_cast<const unsigned char*>(kPskIdentity);
  *idlen = std::strlen(kPskIdentity);
  return 1;
}

int server_psk(SSL* ssl, const unsigned char* identity, std::size_t identity_len,
               SSL_SESSION** sess) {
  *sess = nullptr;
  if (identity_len != std::strlen(kPskIdentity) ||
      std::memcmp(identity, kPskIdentity, identity_len) != 0)
    return 1;  // unknown identity: no PSK, and without a certificate the handshake fails
  SSL_SESSION* s = psk_session(ssl);
  if (s == nullptr) return 0;
  *sess = s;
  return 1;
}

const char* peer_name(TlsRole role) { return role == TlsRole::Server ? "station" : "remote"; }

// PSK mode: whoever shows a certificate is not keyed (anyone can run a TLS 1.3 server with a
// throw-away certificate), so no certificate ever verifies and such a handshake fails at once.
int refuse_any_certificate(int, X509_STORE_CTX* store) {
  X509_STORE_CTX_set_error(store, X509_V_ERR_APPLICATION_VERIFICATION);
  return 0;
}

}  // namespace

std::string TlsConfig::describe() const {
  if (psk) return "TLS 1.3 with --psk";
  if (certificates()) return "TLS 1.3 with certificates";
  return "plain (no --psk or certificates)";
}

void validate_tls_flags(bool has_psk, const std::filesystem::path& cert,
                        const std::filesystem::path& key, const std::filesystem::path& ca) {
  const int given = !cert.empty() + !key.empty() + !ca.empty();
  if (given != 0 && given != 3)
    throw std::invalid_argument(
        "--cert, --key and --ca go together: this daemon's certificate, its private key and the "
        "CA the peer's certificate must chain to");
  if (has_psk && given == 3)
    throw std::invalid_argument(
        "give --psk FILE or --cert/--key/--ca, not both (the peer uses the same kind)");
}

SSL_CTX* make_tls_context(const TlsConfig& config, TlsRole role) {
  if (!config.enabled()) throw std::logic_error("make_tls_context without a key or certificates");
  SSL_CTX* ctx = SSL_CTX_new(TLS_method());
  if (ctx == nullptr) throw std::runtime_error("cannot create a TLS context: " + ssl_errors());
  std::unique_ptr<SSL_CTX, decltype(&SSL_CTX_free)> owned(ctx, &SSL_CTX_free);
  bool ok = SSL_CTX_set_min_proto_version(ctx, TLS1_3_VERSION) == 1 &&
            SSL_CTX_set_max_proto_version(ctx, TLS1_3_VERSION) == 1 &&
            SSL_CTX_set_ciphersuites(ctx, "TLS_AES_256_GCM_SHA384") == 1;
  if (!ok) throw std::logic_error("TLS 1.3 with AES-256-GCM unavailable: " + ssl_errors());
  // psk_ke (a PSK without (EC)DHE, no forward secrecy) is never offered nor accepted.
  SSL_CTX_clear_options(ctx, SSL_OP_ALLOW_NO_DHE_KEX);
  // No resumption: every connection runs a full (EC)DHE handshake under the PSK or certificates.
  SSL_CTX_set_num_tickets(ctx, 0);
  SSL_CTX_set_options(ctx, SSL_OP_NO_TICKET);
  SSL_CTX_set_session_cache_mode(ctx, SSL_SESS_CACHE_OFF);
  if (config.psk) {
    auto* psk = new Psk(derive_psk(*config.psk));
    if (SSL_CTX_set_ex_data(ctx, psk_index(), psk) != 1) {
      delete psk;
      throw std::runtime_error("cannot attach the PSK to the TLS context: " + ssl_errors());
    }
    // The client fails any certificate a server shows; the server asks for none (and a server
    // that verified would need a session id context for its PSK "resumptions"). Both check the
    // session after the handshake (unauthenticated_session).
    if (role == TlsRole::Client) {
      SSL_CTX_set_psk_use_session_callback(ctx, &client_psk);
      SSL_CTX_set_verify(ctx, SSL_VERIFY_PEER, &refuse_any_certificate);
    } else {
      SSL_CTX_set_psk_find_session_callback(ctx, &server_psk);
      SSL_CTX_set_verify(ctx, SSL_VERIFY_NONE, nullptr);
    }
  } else {
    const std::string cert = config.cert.string(), key = config.key.string(),
                      ca = config.ca.string();
    if (SSL_CTX_use_certificate_chain_file(ctx, cert.c_str()) != 1)
      throw std::invalid_argument("--cert '" + cert +
                                  "': cannot load a PEM certificate chain: " + ssl_errors());
    if (SSL_CTX_use_PrivateKey_file(ctx, key.c_str(), SSL_FILETYPE_PEM) != 1)
      throw std::invalid_argument("--key '" + key +
                                  "': cannot load a PEM private key: " + ssl_errors());
    if (SSL_CTX_check_private_key(ctx) != 1)
      throw std::invalid_argument("--key '" + key + "' does not belong to --cert '" + cert +
                                  "': " + ssl_errors());
    if (SSL_CTX_load_verify_locations(ctx, ca.c_str(), nullptr) != 1)
      throw std::invalid_argument("--ca '" + ca +
                                  "': cannot load PEM CA certificates: " + ssl_errors());
    // Mutual: the station verifies the remote's chain, the remote requires and verifies the
    // station's. The default verify purpose checks the server/client extended key usage.
    SSL_CTX_set_verify(ctx, SSL_VERIFY_PEER | SSL_VERIFY_FAIL_IF_NO_PEER_CERT, nullptr);
  }
  ERR_clear_error();
  return owned.release();
}

LinkKeys export_link_keys(SSL* ssl, TlsRole role) {
  const auto one = [ssl](const char* label) {
    std::array<std::uint8_t, kSealKeyBytes + kSealNonceBytes> b{};
    if (SSL_export_keying_material(ssl, b.data(), b.size(), label, std::strlen(label), nullptr, 0,
                                   0) != 1)
      throw std::runtime_error(std::string("TLS exporter failed for '") + label +
                               "': " + ssl_errors());
    DirectionKey k = DirectionKey::from_bytes(b);
    OPENSSL_cleanse(b.data(), b.size());
    return k;
  };
  LinkKeys keys;
  const bool server = role == TlsRole::Server;
  keys.tx = one(server ? kExporterRemoteToStation : kExporterStationToRemote);
  keys.rx = one(server ? kExporterStationToRemote : kExporterRemoteToStation);
  return keys;
}

std::optional<std::string> unauthenticated_session(SSL* ssl, TlsRole role,
                                                   const TlsConfig& config) {
  const std::string peer = peer_name(role);
  if (config.psk) {
    // An external PSK handshake is OpenSSL's "resumption": anything else authenticated nobody.
    if (SSL_session_reused(ssl) != 1)
      return "the " + peer +
             " completed TLS without the shared key (no PSK was used): it does not hold this "
             "--psk key, so it is not the " +
             peer + " it claims to be; nothing was sent";
    if (SSL_get0_peer_certificate(ssl) != nullptr)
      return "the " + peer + " showed a certificate in --psk mode; nothing was sent";
    return std::nullopt;
  }
  if (config.certificates() &&
      (SSL_get0_peer_certificate(ssl) == nullptr || SSL_get_verify_result(ssl) != X509_V_OK))
    return "the " + peer + "'s certificate was not verified against --ca '" + config.ca.string() +
           "'; nothing was sent";
  return std::nullopt;
}

bool tls_failure_is_plain_peer(unsigned long e) {
  if (ERR_GET_LIB(e) != ERR_LIB_SSL) return false;
  switch (ERR_GET_REASON(e)) {
    case SSL_R_WRONG_VERSION_NUMBER:
    case SSL_R_PACKET_LENGTH_TOO_LONG:
    case SSL_R_HTTP_REQUEST:
    case SSL_R_UNKNOWN_PROTOCOL:
    case SSL_R_RECORD_LENGTH_MISMATCH:
    case SSL_R_UNEXPECTED_RECORD:
      return true;
    default:
      return false;
  }
}

std::string explain_tls_failure(unsigned long e, const std::string& text, TlsRole role,
                                const TlsConfig& config) {
  const std::string peer = peer_name(role);
  const std::string same = config.psk ? "the same --psk FILE" : "certificates from the same --ca";
  if (tls_failure_is_plain_peer(e))
    return "the " + peer +
           " does not speak TLS (it runs without --psk or certificates): start both daemons "
           "with " +
           same + " (" + text + ")";
  const int reason = ERR_GET_LIB(e) == ERR_LIB_SSL ? ERR_GET_REASON(e) : 0;
  if (config.psk) {
    if (reason == SSL_R_CERTIFICATE_VERIFY_FAILED)
      return "the " + peer +
             " answered with a certificate, not the shared key: it does not hold this --psk key "
             "(an impostor on the path, or a " +
             peer + " started with --cert/--key/--ca); give both daemons the same --psk FILE (" +
             text + ")";
    if (reason == SSL_R_BINDER_DOES_NOT_VERIFY)
      return "key mismatch: the station's --psk key differs from this telex-remote's (the TLS "
             "PSK binder does not verify); give both daemons the same key file (" +
             text + ")";
    // OpenSSL's server answers a PSK binder that does not verify with an illegal_parameter
    // alert (RFC 8446 4.2.11 suggests decrypt_error): either means the keys differ.
    if (reason == SSL_R_SSLV3_ALERT_ILLEGAL_PARAMETER ||
        reason == SSL_R_TLSV1_ALERT_DECRYPT_ERROR || reason == SSL_R_DECRYPTION_FAILED)
      return "key mismatch: the " + peer +
             " refused this daemon's key: the two daemons' --psk keys differ (" + text + ")";
    if (reason == SSL_R_SSLV3_ALERT_HANDSHAKE_FAILURE || reason == SSL_R_NO_SHARED_CIPHER ||
        reason == SSL_R_NO_SUITABLE_SIGNATURE_ALGORITHM ||
        reason == SSL_R_TLSV13_ALERT_CERTIFICATE_REQUIRED)
      return "the " + peer +
             " does not use a pre-shared key (certificates?): give both daemons the same --psk "
             "FILE (" +
             text + ")";
  } else {
    if (reason == SSL_R_CERTIFICATE_VERIFY_FAILED)
      return "the " + peer + "'s certificate does not verify against --ca '" + config.ca.string() +
             "' (" + text + ")";
    if (reason == SSL_R_TLSV1_ALERT_UNKNOWN_CA || reason == SSL_R_SSLV3_ALERT_BAD_CERTIFICATE ||
        reason == SSL_R_SSLV3_ALERT_CERTIFICATE_UNKNOWN ||
        reason == SSL_R_SSLV3_ALERT_UNSUPPORTED_CERTIFICATE)
      return "the " + peer + " does not accept this daemon's certificate --cert '" +
             config.cert.string() + "' (signed by another CA?) (" + text + ")";
    if (reason == SSL_R_PEER_DID_NOT_RETURN_A_CERTIFICATE ||
        reason == SSL_R_TLSV13_ALERT_CERTIFICATE_REQUIRED)
      return "the " + peer + " presented no certificate: give both daemons --cert/--key/--ca (" +
             text + ")";
    if (reason == SSL_R_SSLV3_ALERT_HANDSHAKE_FAILURE || reason == SSL_R_NO_SHARED_CIPHER ||
        reason == SSL_R_TLSV1_ALERT_DECRYPT_ERROR)
      return "the " + peer +
             " does not use certificates (a --psk key?): give both daemons --cert/--key/--ca (" +
             text + ")";
  }
  return "TLS handshake with the " + peer + " failed: " + text;
}

namespace {
std::string strip_brackets(const std::string& host) {
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
    return host.substr(1, host.size() - 2);
  return host;
}
}  // namespace

std::vector<std::string> resolve_host(const std::string& host) {
  const std::string h = strip_brackets(host);
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* res = nullptr;
  const int rc = getaddrinfo(h.c_str(), nullptr, &hints, &res);
  if (rc != 0 || res == nullptr)
    throw std::invalid_argument("cannot resolve '" + host + "': " + gai_strerror(rc));
  std::vector<std::string> out;
  char buf[INET6_ADDRSTRLEN];
  for (addrinfo* p = res; p != nullptr; p = p->ai_next) {
    const void* a =
        p->ai_family == AF_INET
            ? static_cast<const void*>(&reinterpret_cast<sockaddr_in*>(p->ai_addr)->sin_addr)
            : static_cast<const void*>(&reinterpret_cast<sockaddr_in6*>(p->ai_addr)->sin6_addr);
    if (inet_ntop(p->ai_family, a, buf, sizeof buf) != nullptr &&
        std::find(out.begin(), out.end(), buf) == out.end())
      out.emplace_back(buf);
  }
  freeaddrinfo(res);
  if (out.empty()) throw std::invalid_argument("cannot resolve '" + host + "': no address");
  return out;
}

bool is_loopback_address(const std::string& address) {
  const std::string h = strip_brackets(address);
  in_addr v4{};
  if (inet_pton(AF_INET, h.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  if (inet_pton(AF_INET6, h.c_str(), &v6) == 1) {
    if (IN6_IS_ADDR_LOOPBACK(&v6)) return true;
    if (IN6_IS_ADDR_V4MAPPED(&v6)) return v6.s6_addr[12] == 127;
  }
  return false;
}

bool is_loopback_host(const std::string& host) {
  if (host == "localhost") return true;
  try {
    const auto addresses = resolve_host(host);
    return std::all_of(addresses.begin(), addresses.end(), is_loopback_address);
  } catch (const std::invalid_argument&) {
    return false;
  }
}

std::string insecure_refusal(const std::string& flag, const std::string& address) {
  return flag + " " + address +
         " is not a loopback address and neither --psk FILE nor --cert/--key/--ca is given: "
         "anyone on the network could move the robot head and watch its cameras and depth. Give "
         "both daemons the same --psk FILE (or certificates from one CA), or pass --insecure to "
         "accept that risk";
}

std::string insecure_warning() {
  return "INSECURE (--insecure): the link is neither encrypted nor authenticated; anyone on the "
         "network can move the robot head and watch its cameras and depth";
}

}  // namespace telex::proto
