// SPDX-License-Identifier: MIT
// The pre-shared key (--psk FILE): its file, its permissions, and wiping it; TLS uses it (tls.h).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

namespace telex::proto {

// 32 bytes: a random key of the TLS suite's strength. A typed password of 16 characters has far
// less entropy and the PSK is not stretched: `telex keygen FILE` writes a proper one.
inline constexpr std::size_t kMinKeyBytes = 32;
inline constexpr std::size_t kMaxKeyBytes = 1024;

// A pre-shared key. Its bytes are wiped when it goes away.
class AuthKey {
 public:
  // Throws std::invalid_argument when shorter than kMinKeyBytes or longer than kMaxKeyBytes.
  explicit AuthKey(std::span<const std::uint8_t> bytes);
  ~AuthKey();
  AuthKey(const AuthKey& other);
  AuthKey& operator=(const AuthKey& other);
  std::span<const std::uint8_t> bytes() const { return bytes_; }

 private:
  std::vector<std::uint8_t> bytes_;
};

// Reads the whole file as the key (raw bytes). One trailing newline (LF or CRLF) is dropped since
// editors and `openssl rand -hex 32 > key` add it; `head -c 32 /dev/urandom > key` is used as is.
// Throws std::runtime_error naming the path when it cannot be read, and
// std::invalid_argument naming it when the key is too short or too long.
AuthKey load_key_file(const std::filesystem::path& path);

// Writes kMinKeyBytes from the system random source to a new file `path` with mode 0600 (the
// file must not exist). Throws std::runtime_error naming the path when it cannot.
void write_new_key_file(const std::filesystem::path& path);

// Throws std::invalid_argument naming the path when group or others may read or write the key
// file (its mode must be 0600 or 0400, as for ssh keys); std::runtime_error when it cannot stat.
// `what` names the file in the message ("pre-shared key file", "private key file").
void check_key_file_permissions(const std::filesystem::path& path,
                                const char* what = "pre-shared key file");

// `--psk FILE` as both daemons read it: the permissions checked, then the key loaded. Throws
// std::invalid_argument "--psk: <what is wrong>" for any of the errors above.
AuthKey load_psk_flag(const std::filesystem::path& path);

// 64 bits from the operating system's random source (session ids).
std::uint64_t random_u64();

}  // namespace telex::proto
