// SPDX-License-Identifier: MIT
// A private CA and the two daemons' certificates for --cert/--key/--ca (`telex certs DIR`), made
// with OpenSSL: EC P-256 keys, SHA-256 signatures, the key usages TLS checks.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace telex::proto {

struct LinkCertificates {
  std::filesystem::path ca_cert, ca_key;            // ca.pem, ca.key: keep ca.key offline
  std::filesystem::path remote_cert, remote_key;    // remote.pem, remote.key
  std::filesystem::path station_cert, station_key;  // station.pem, station.key
};

// Makes, in `dir` (created if missing; no file in it may exist yet):
//  - ca.pem / ca.key: a self-signed CA (basicConstraints CA:TRUE critical, keyUsage keyCertSign
//    and cRLSign);
//  - remote.pem / remote.key: the remote's, extendedKeyUsage serverAuth, subjectAltName from
//    `remote_names` (DNS names or IP addresses; the link does not check them today, a peer may);
//  - station.pem / station.key: the station's, extendedKeyUsage clientAuth.
// Each certificate is valid for `days` days from now; keys are written with mode 0600.
// Throws std::runtime_error naming the file or the OpenSSL step that failed.
LinkCertificates make_link_certificates(const std::filesystem::path& dir, int days,
                                        const std::vector<std::string>& remote_names);

}  // namespace telex::proto
