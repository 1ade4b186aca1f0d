// SPDX-License-Identifier: MIT
// The link's security flags (link_security.h).
#include "telex/cli/link_security.h"

#include <openssl/ssl.h>

#include <CLI/CLI.hpp>
#include <cctype>

#include "telex/proto/auth.h"

namespace telex::cli {
namespace {

std::string sentence(std::string s, bool capital) {
  if (capital && !s.empty())
    s[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(s[0])));
  return s;
}

}  // namespace

void add_link_security(CLI::App& app, LinkSecurityFlags& f, const LinkSecurityNames& n) {
  const bool c = n.sentence_case;
  app.add_option("--psk", f.psk_file,
                 sentence("pre-shared key FILE (32..1024 random bytes, mode 0600; `telex keygen "
                          "FILE` writes one): TLS 1.3 with this key and (EC)DHE on TCP, sealed "
                          "datagrams on UDP; the " +
                              n.peer + " needs the same key",
                          c));
  app.add_option("--cert", f.cert_file,
                 sentence("this " + n.self +
                              "'s certificate chain FILE (PEM), instead of --psk; with --key and "
                              "--ca",
                          c));
  app.add_option("--key", f.key_file,
                 sentence("the private key FILE (PEM, mode 0600) of --cert", c));
  app.add_option(
      "--ca", f.ca_file,
      "CA FILE (PEM): the " + n.peer + "'s certificate must chain to it (required, verified)");
  app.add_flag("--insecure", f.insecure,
               sentence("accept a " + n.address_flag +
                            " address off loopback without --psk or certificates: anyone on the "
                            "network can then move the robot head and watch its cameras and depth",
                        c));
}

proto::TlsConfig load_link_security(const LinkSecurityFlags& f, proto::TlsRole role) {
  proto::validate_tls_flags(!f.psk_file.empty(), f.cert_file, f.key_file, f.ca_file);
  proto::TlsConfig tls;
  if (!f.psk_file.empty()) tls.psk = proto::load_psk_flag(f.psk_file);
  if (!f.cert_file.empty()) {
    proto::check_key_file_permissions(f.key_file, "private key file");
    tls.cert = f.cert_file;
    tls.key = f.key_file;
    tls.ca = f.ca_file;
  }
  // Built once here and thrown away, so an unreadable or mismatched file exits 2 before anything
  // starts (the daemons build their own when they start).
  if (tls.certificates()) SSL_CTX_free(proto::make_tls_context(tls, role));
  return tls;
}

}  // namespace telex::cli
