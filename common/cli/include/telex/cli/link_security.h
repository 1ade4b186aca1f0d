// SPDX-License-Identifier: MIT
// The link's security flags, declared and loaded once for both daemons: --psk FILE, or
// --cert/--key/--ca, or --insecure for a plain link off loopback (docs/PROTOCOL.md).
#pragma once

#include <string>

#include "telex/cli/command_line.h"
#include "telex/proto/tls.h"

namespace telex::cli {

struct LinkSecurityFlags {
  std::string psk_file, cert_file, key_file, ca_file;
  bool insecure = false;
};

// Who is speaking and to whom, for the help texts: self "station", peer "remote", address_flag
// "--connect" (or "remote", "station", "--listen"); sentence_case: the program's help texts
// start with a capital.
struct LinkSecurityNames {
  std::string self, peer, address_flag;
  bool sentence_case = false;
};

void add_link_security(CLI::App& app, LinkSecurityFlags& f, const LinkSecurityNames& names);

// The flags' TLS configuration, every file read and checked now (the key's mode, the PSK's
// length; the certificate, key and CA loaded into a throw-away context of `role`), so a bad file
// exits 2 before anything starts. Empty (not enabled) without --psk or --cert. Throws
// std::invalid_argument naming the flag.
proto::TlsConfig load_link_security(const LinkSecurityFlags& f, proto::TlsRole role);

}  // namespace telex::cli
