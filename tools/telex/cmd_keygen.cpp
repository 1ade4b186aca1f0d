// SPDX-License-Identifier: MIT
// `telex keygen FILE`: a new pre-shared key for --psk, 32 random bytes with mode 0600. Copy the
// same file to both machines (scp keeps it private); a key is never overwritten.
#include <iostream>
#include <string>

#include "command.h"
#include "telex/proto/auth.h"

namespace telex::tool {
namespace {

const RegisterCommand kKeygen{
    "keygen", "Write a new random pre-shared key for --psk (32 bytes, mode 0600)",
    [](cli::CommandLine& app) -> std::function<int()> {
      auto path = std::make_shared<std::string>();
      app.add_option("file", *path, "The key file to create (it must not exist)").required();
      return [path] {
        try {
          proto::write_new_key_file(*path);
        } catch (const std::exception& e) {
          std::cerr << "telex keygen: " << e.what() << "\n";
          return 1;
        }
        std::cout << "wrote a new 32-byte key to " << *path
                  << " (mode 0600); give both daemons --psk " << *path << "\n";
        return 0;
      };
    }};

}  // namespace
}  // namespace telex::tool
