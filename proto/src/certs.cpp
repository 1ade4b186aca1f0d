// SPDX-License-Identifier: MIT
// A private CA and the daemons' certificates (certs.h), through OpenSSL's X509 API.
#include "telex/proto/certs.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/rand.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>
#include <unistd.h>

#include <cstdio>
#include <memory>
#include <stdexcept>

namespace telex::proto {
namespace {

using Key = std::unique_ptr<EVP_PKEY, decltype(&EVP_PKEY_free)>;
using Cert = std::unique_ptr<X509, decltype(&X509_free)>;

[[noreturn]] void fail(const std::string& step) {
  char buf[256] = "unknown OpenSSL error";
  if (const unsigned long e = ERR_get_error()) ERR_error_string_n(e, buf, sizeof buf);
  throw std::runtime_error("telex certs: " + step + ": " + buf);
}

Key new_key() {
  Key k(EVP_EC_gen("P-256"), &EVP_PKEY_free);
  if (!k) fail("EC P-256 key generation");
  return k;
}

void add_ext(X509* cert, X509* issuer, int nid, const char* value) {
  X509V3_CTX ctx;
  X509V3_set_ctx_nodb(&ctx);
  X509V3_set_ctx(&ctx, issuer, cert, nullptr, nullptr, 0);
  X509_EXTENSION* ext = X509V3_EXT_conf_nid(nullptr, &ctx, nid, value);
  if (ext == nullptr || X509_add_ext(cert, ext, -1) != 1) fail(std::string("extension ") + value);
  X509_EXTENSION_free(ext);
}

// An unsigned certificate for `name` with `key`, issued by `issuer` (null: self-issued).
Cert make_cert(const std::string& name, EVP_PKEY* key, X509* issuer, int days) {
  Cert c(X509_new(), &X509_free);
  if (!c) fail("X509_new");
  unsigned char serial[16];
  if (RAND_bytes(serial, sizeof serial) != 1) fail("serial number");
  serial[0] &= 0x7F;  // positive
  std::unique_ptr<BIGNUM, decltype(&BN_free)> bn(BN_bin2bn(serial, sizeof serial, nullptr),
                                                 &BN_free);
  X509_set_version(c.get(), X509_VERSION_3);
  if (!bn || BN_to_ASN1_INTEGER(bn.get(), X509_get_serialNumber(c.get())) == nullptr)
    fail("serial number");
  X509_gmtime_adj(X509_getm_notBefore(c.get()), -60);
  X509_gmtime_adj(X509_getm_notAfter(c.get()), static_cast<long>(days) * 86400);
  X509_NAME* subject = X509_get_subject_name(c.get());
  X509_NAME_add_entry_by_txt(subject, "O", MBSTRING_ASC,
                             reinterpret_cast<const unsigned char*>("telex"), -1, -1, 0);
  X509_NAME_add_entry_by_txt(subject, "CN", MBSTRING_ASC,
                             reinterpret_cast<const unsigned char*>(name.c_str()), -1, -1, 0);
  X509_set_issuer_name(c.get(), issuer ? X509_get_subject_name(issuer) : subject);
  X509_set_pubkey(c.get(), key);
  X509* signer = issuer ? issuer : c.get();
  add_ext(c.get(), signer, NID_subject_key_identifier, "hash");
  add_ext(c.get(), signer, NID_authority_key_identifier, "keyid:always");
  return c;
}

void sign(X509* cert, EVP_PKEY* key) {
  if (X509_sign(cert, key, EVP_sha256()) == 0) fail("signing");
}

void write_cert(const std::filesystem::path& p, X509* cert) {
  std::unique_ptr<FILE, decltype(&std::fclose)> f(std::fopen(p.c_str(), "wx"), &std::fclose);
  if (!f || PEM_write_X509(f.get(), cert) != 1)
    throw std::runtime_error("telex certs: cannot write '" + p.string() + "' (does it exist?)");
}

void write_key(const std::filesystem::path& p, EVP_PKEY* key) {
  const int fd = ::open(p.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  std::unique_ptr<FILE, decltype(&std::fclose)> f(fd >= 0 ? ::fdopen(fd, "w") : nullptr,
                                                  &std::fclose);
  if (!f) {
    if (fd >= 0) ::close(fd);
    throw std::runtime_error("telex certs: cannot create '" + p.string() + "' (does it exist?)");
  }
  if (PEM_write_PrivateKey(f.get(), key, nullptr, nullptr, 0, nullptr, nullptr) != 1)
    fail("writing " + p.string());
}

std::string subject_alt_names(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) {
    in6_addr a6{};
    in_addr a4{};
    const bool ip =
        inet_pton(AF_INET, n.c_str(), &a4) == 1 || inet_pton(AF_INET6, n.c_str(), &a6) == 1;
    out += (out.empty() ? "" : ",") + std::string(ip ? "IP:" : "DNS:") + n;
  }
  return out;
}

}  // namespace

LinkCertificates make_link_certificates(const std::filesystem::path& dir, int days,
                                        const std::vector<std::string>& remote_names) {
  if (days <= 0) throw std::invalid_argument("--days must be > 0");
  std::filesystem::create_directories(dir);
  LinkCertificates out{dir / "ca.pem",     dir / "ca.key",      dir / "remote.pem",
                       dir / "remote.key", dir / "station.pem", dir / "station.key"};
  for (const auto& p : {out.ca_cert, out.ca_key, out.remote_cert, out.remote_key, out.station_cert,
                        out.station_key})
    if (std::filesystem::exists(p))
      throw std::runtime_error("telex certs: '" + p.string() +
                               "' exists; certificates are never overwritten (use a new folder)");
  const Key ca_key = new_key();
  const Cert ca = make_cert("telex CA", ca_key.get(), nullptr, days);
  add_ext(ca.get(), ca.get(), NID_basic_constraints, "critical,CA:TRUE,pathlen:0");
  add_ext(ca.get(), ca.get(), NID_key_usage, "critical,keyCertSign,cRLSign");
  sign(ca.get(), ca_key.get());
  const auto leaf = [&](const std::string& name, const char* eku, const std::string& san) {
    Key key = new_key();
    Cert c = make_cert(name, key.get(), ca.get(), days);
    add_ext(c.get(), ca.get(), NID_basic_constraints, "critical,CA:FALSE");
    add_ext(c.get(), ca.get(), NID_key_usage, "critical,digitalSignature");
    add_ext(c.get(), ca.get(), NID_ext_key_usage, eku);
    if (!san.empty()) add_ext(c.get(), ca.get(), NID_subject_alt_name, san.c_str());
    sign(c.get(), ca_key.get());
    return std::pair{std::move(key), std::move(c)};
  };
  const auto [remote_key, remote] =
      leaf("telex-remote", "serverAuth", subject_alt_names(remote_names));
  const auto [station_key, station] = leaf("telex-local", "clientAuth", "");
  write_key(out.ca_key, ca_key.get());
  write_cert(out.ca_cert, ca.get());
  write_key(out.remote_key, remote_key.get());
  write_cert(out.remote_cert, remote.get());
  write_key(out.station_key, station_key.get());
  write_cert(out.station_cert, station.get());
  return out;
}

}  // namespace telex::proto
