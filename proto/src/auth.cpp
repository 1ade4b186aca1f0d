// SPDX-License-Identifier: MIT
// Pre-shared key files: loading, permissions, wiping; the system random source.
#include "telex/proto/auth.h"

#include <fcntl.h>
#include <openssl/crypto.h>
#include <openssl/rand.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>

namespace telex::proto {

AuthKey::AuthKey(std::span<const std::uint8_t> bytes) : bytes_(bytes.begin(), bytes.end()) {
  if (bytes_.size() < kMinKeyBytes)
    throw std::invalid_argument("pre-shared key is " + std::to_string(bytes_.size()) +
                                " bytes; at least " + std::to_string(kMinKeyBytes) + " are needed");
  if (bytes_.size() > kMaxKeyBytes)
    throw std::invalid_argument("pre-shared key is " + std::to_string(bytes_.size()) +
                                " bytes; at most " + std::to_string(kMaxKeyBytes) + " are allowed");
}

AuthKey::~AuthKey() {
  if (!bytes_.empty()) OPENSSL_cleanse(bytes_.data(), bytes_.size());
}

AuthKey::AuthKey(const AuthKey& other) = default;

AuthKey& AuthKey::operator=(const AuthKey& other) {
  if (this != &other) {
    if (!bytes_.empty()) OPENSSL_cleanse(bytes_.data(), bytes_.size());
    bytes_ = other.bytes_;
  }
  return *this;
}

AuthKey load_key_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read pre-shared key file '" + path.string() + "'");
  std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                  std::istreambuf_iterator<char>());
  if (in.bad())
    throw std::runtime_error("error reading pre-shared key file '" + path.string() + "'");
  // One trailing newline is an editor's, not the key's.
  if (!bytes.empty() && bytes.back() == '\n') {
    bytes.pop_back();
    if (!bytes.empty() && bytes.back() == '\r') bytes.pop_back();
  }
  try {
    AuthKey key(bytes);
    OPENSSL_cleanse(bytes.data(), bytes.size());
    return key;
  } catch (const std::invalid_argument& e) {
    if (!bytes.empty()) OPENSSL_cleanse(bytes.data(), bytes.size());
    throw std::invalid_argument("pre-shared key file '" + path.string() + "': " + e.what() +
                                " (`telex keygen FILE` writes a random one)");
  }
}

AuthKey load_psk_flag(const std::filesystem::path& path) {
  try {
    check_key_file_permissions(path);
    return load_key_file(path);
  } catch (const std::exception& e) {
    throw std::invalid_argument(std::string("--psk: ") + e.what());
  }
}

void check_key_file_permissions(const std::filesystem::path& path, const char* what) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0)
    throw std::runtime_error(std::string("cannot read ") + what + " '" + path.string() +
                             "': " + std::strerror(errno));
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    throw std::invalid_argument(std::string(what) + " '" + path.string() + "' has mode " + mode +
                                ": group and others must have no access (chmod 600 '" +
                                path.string() + "')");
  }
}

void write_new_key_file(const std::filesystem::path& path) {
  std::array<std::uint8_t, kMinKeyBytes> key{};
  if (RAND_bytes(key.data(), static_cast<int>(key.size())) != 1)
    throw std::runtime_error("the system random source failed (OpenSSL RAND_bytes)");
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) {
    OPENSSL_cleanse(key.data(), key.size());
    throw std::runtime_error(
        "cannot create key file '" + path.string() + "': " + std::strerror(errno) +
        (errno == EEXIST ? " (a key is never overwritten: remove it first)" : ""));
  }
  const ssize_t n = ::write(fd, key.data(), key.size());
  OPENSSL_cleanse(key.data(), key.size());
  const bool ok = n == static_cast<ssize_t>(key.size()) && ::fsync(fd) == 0;
  ::close(fd);
  if (!ok) {
    std::filesystem::remove(path);
    throw std::runtime_error("cannot write key file '" + path.string() + "'");
  }
}

std::uint64_t random_u64() {
  std::uint64_t v = 0;
  if (RAND_bytes(reinterpret_cast<unsigned char*>(&v), sizeof v) != 1)
    throw std::runtime_error("the system random source failed (OpenSSL RAND_bytes)");
  return v;
}

}  // namespace telex::proto
