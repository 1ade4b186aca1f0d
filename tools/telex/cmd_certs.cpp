// SPDX-License-Identifier: MIT
// `telex certs DIR [--days N] [--remote-name NAME]...`: a private CA and the remote's and the
// station's certificates for --cert/--key/--ca (proto/certs.h), and the two command lines to use.
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "command.h"
#include "telex/proto/certs.h"

namespace telex::tool {
namespace {

struct CertsArgs {
  std::string dir;
  int days = 825;
  std::vector<std::string> remote_names;
};

int run_certs(const CertsArgs& a) {
  if (a.days <= 0) {
    std::cerr << "telex certs: --days " << a.days << " is out of range (valid: > 0)\n";
    return 2;
  }
  proto::LinkCertificates c;
  try {
    c = proto::make_link_certificates(a.dir, a.days, a.remote_names);
  } catch (const std::exception& e) {
    std::cerr << e.what() << "\n";
    return 1;
  }
  std::cout << "wrote a CA and two certificates valid " << a.days << " days to " << a.dir
            << "\n  on the robot:  telex-remote --cert " << c.remote_cert.string() << " --key "
            << c.remote_key.string() << " --ca " << c.ca_cert.string()
            << "\n  the station:   telex-local --cert " << c.station_cert.string() << " --key "
            << c.station_key.string() << " --ca " << c.ca_cert.string() << "\nCopy each "
            << "machine's .pem and .key (mode 0600) and ca.pem to it; keep " << c.ca_key.string()
            << " off both.\n";
  return 0;
}

const RegisterCommand kCerts{
    "certs", "Make a private CA and the remote's and station's certificates for --cert/--key/--ca",
    [](cli::CommandLine& app) -> std::function<int()> {
      auto a = std::make_shared<CertsArgs>();
      app.add_option("dir", a->dir, "The folder to write into (no file there is overwritten)")
          .required();
      app.add_option("--days", a->days, "Validity of the CA and certificates, in days");
      app.add_option("--remote-name", a->remote_names,
                     "A DNS name or IP address of the remote for its certificate's "
                     "subjectAltName; repeatable");
      return [a] { return run_certs(*a); };
    }};

}  // namespace
}  // namespace telex::tool
