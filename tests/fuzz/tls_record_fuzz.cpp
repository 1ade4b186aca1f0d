// SPDX-License-Identifier: MIT
// libFuzzer target for what an attacker on the link can send since version 4: arbitrary bytes as
// TLS records to the remote's handshake (server, --psk) and to the station's (client, after its
// ClientHello), as a sealed datagram to the opener (whatever opens goes through the reassembler
// and the datagram parser, as on the station), and as stream bytes to the stream parser.
#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/ssl.h>

#include <cstdint>
#include <cstdlib>
#include <span>

#include "telex/proto/fragment.h"
#include "telex/proto/parser.h"
#include "telex/proto/seal.h"
#include "telex/proto/tls.h"

namespace {

using namespace telex::proto;

SSL_CTX* context(TlsRole role) {
  TlsConfig c;
  c.psk = AuthKey(std::vector<std::uint8_t>(32, 0x42));
  return make_tls_context(c, role);
}

// Feeds `bytes` to a fresh SSL end as what its peer sent; it must fail or wait, never finish.
void feed_handshake(SSL_CTX* ctx, bool client, std::span<const std::uint8_t> bytes) {
  SSL* ssl = SSL_new(ctx);
  BIO* in = BIO_new(BIO_s_mem());
  BIO* out = BIO_new(BIO_s_mem());
  SSL_set_bio(ssl, in, out);  // ssl owns both
  if (client) {
    SSL_set_connect_state(ssl);
    (void)SSL_do_handshake(ssl);  // writes its ClientHello into `out`
  } else {
    SSL_set_accept_state(ssl);
  }
  BIO_write(in, bytes.data(), static_cast<int>(bytes.size()));
  for (int i = 0; i < 4; ++i) {
    const int r = SSL_do_handshake(ssl);
    // Finishing needs the PSK's binder and Finished MACs: bytes without the key never get there.
    if (r == 1) std::abort();
    if (SSL_get_error(ssl, r) != SSL_ERROR_WANT_READ) break;
  }
  ERR_clear_error();
  SSL_free(ssl);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static SSL_CTX* const server = context(TlsRole::Server);
  static SSL_CTX* const client = context(TlsRole::Client);
  const std::span<const std::uint8_t> rest(data + 1, size - 1);

  feed_handshake((data[0] & 1) ? client : server, (data[0] & 1) != 0, rest);

  // The station's datagram path: opener, reassembler, parser.
  DirectionKey key;
  key.key.fill(0x42);
  key.iv.fill(0x24);
  DatagramOpener opener(key);
  std::vector<std::uint8_t> plain;
  if (opener.open(rest, plain) == OpenError::None) {
    std::vector<std::uint8_t> again;
    if (opener.open(rest, again) != OpenError::Replayed) std::abort();
    Reassembler reassembler;
    DatagramParser parser;
    parser.set_frame_size(640, 480);
    if (auto whole = reassembler.push(plain, 0)) (void)parser.parse(*whole);
  } else if (!plain.empty()) {
    std::abort();  // nothing of an unauthentic datagram may come out
  }

  // The plaintext stream behind TLS.
  StreamParser stream;
  std::span<const std::uint8_t> in = rest;
  while (!in.empty()) {
    const std::size_t took = stream.feed(in);
    in = in.subspan(took);
    while (stream.next()) {
    }
    if (took == 0) break;
  }
  return 0;
}
