// SPDX-License-Identifier: MIT
// `telex codec`: ratio and speed of our depth codecs against zlib, zstd, PNG and RVL on one frame.
#include <time.h>
#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <functional>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "command.h"
#include "telex/common/depth_io.h"
#include "telex/proto/depth_codec.h"

namespace telex::tool {
namespace {

using Bytes = std::vector<std::uint8_t>;

struct Candidate {
  std::string name;
  bool ours;
  std::function<Bytes(const cv::Mat1w&)> encode;
  std::function<bool(const Bytes&, cv::Mat1w&)> decode;  // false when the decoder refused
};

struct Measured {
  std::string name;
  bool ours;
  double ratio;
  double encode_ms;
  double decode_ms;
  bool lossless;
  std::size_t bytes;
};

std::span<const std::uint8_t> raw_bytes(const cv::Mat1w& m) {
  return {m.data, m.total() * m.elemSize()};
}

Candidate zlib_peer(int level) {
  return {"zlib-" + std::to_string(level), false,
          [level](const cv::Mat1w& m) {
            const auto in = raw_bytes(m);
            uLongf n = compressBound(in.size());
            Bytes out(n);
            if (compress2(out.data(), &n, in.data(), in.size(), level) != Z_OK)
              throw std::runtime_error("zlib compress2 failed");
            out.resize(n);
            return out;
          },
          [](const Bytes& b, cv::Mat1w& out) {
            uLongf n = out.total() * 2;
            return uncompress(out.data, &n, b.data(), b.size()) == Z_OK && n == out.total() * 2;
          }};
}

Candidate zstd_peer(int level) {
  return {"zstd-" + std::to_string(level), false,
          [level](const cv::Mat1w& m) {
            const auto in = raw_bytes(m);
            Bytes out(ZSTD_compressBound(in.size()));
            const std::size_t n =
                ZSTD_compress(out.data(), out.size(), in.data(), in.size(), level);
            if (ZSTD_isError(n)) throw std::runtime_error("zstd compress failed");
            out.resize(n);
            return out;
          },
          [](const Bytes& b, cv::Mat1w& out) {
            const std::size_t n = ZSTD_decompress(out.data, out.total() * 2, b.data(), b.size());
            return !ZSTD_isError(n) && n == out.total() * 2;
          }};
}

Candidate png_peer(int level) {
  return {"png-" + std::to_string(level), false,
          [level](const cv::Mat1w& m) {
            Bytes out;
            if (!cv::imencode(".png", m, out, {cv::IMWRITE_PNG_COMPRESSION, level}))
              throw std::runtime_error("PNG encode failed");
            return out;
          },
          [](const Bytes& b, cv::Mat1w& out) {
            cv::Mat d = cv::imdecode(b, cv::IMREAD_UNCHANGED);
            if (d.type() != CV_16UC1 || d.size() != out.size()) return false;
            d.copyTo(out);
            return true;
          }};
}

Candidate ours(proto::Codec codec, int zip_level) {
  return {std::string(proto::codec_name(codec)), true,
          [=](const cv::Mat1w& m) { return proto::encode_depth(m, codec, zip_level); },
          [=](const Bytes& b, cv::Mat1w& out) {
            return proto::decode_depth(b, out.cols, out.rows, codec, out) ==
                   proto::DecodeStatus::Ok;
          }};
}

// Tiles are concatenated with a u32 length each, as they would travel in separate messages.
Candidate tiled(proto::Codec codec, int zip_level, int tw, int th) {
  const std::string name = std::string(proto::codec_name(codec)) + "-tiled-" + std::to_string(tw) +
                           "x" + std::to_string(th);
  return {name, true,
          [=](const cv::Mat1w& m) {
            const proto::TileGrid grid{m.cols, m.rows, tw, th};
            Bytes out;
            for (const auto& t : proto::encode_tiles(m, grid, codec, zip_level)) {
              const auto n = static_cast<std::uint32_t>(t.bytes.size());
              for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(n >> (8 * i)));
              out.insert(out.end(), t.bytes.begin(), t.bytes.end());
            }
            return out;
          },
          [=](const Bytes& b, cv::Mat1w& out) {
            const proto::TileGrid grid{out.cols, out.rows, tw, th};
            std::size_t pos = 0;
            for (int i = 0; i < grid.count(); ++i) {
              if (b.size() - pos < 4) return false;
              const std::uint32_t n = b[pos] | b[pos + 1] << 8 | b[pos + 2] << 16 |
                                      static_cast<std::uint32_t>(b[pos + 3]) << 24;
              pos += 4;
              if (b.size() - pos < n) return false;
              if (proto::decode_tile_into({b.data() + pos, n}, grid, i, codec, out) !=
                  proto::DecodeStatus::Ok)
                return false;
              pos += n;
            }
            return pos == b.size();
          }};
}

Candidate rvl_peer() {
  return {"rvl-ref", false, [](const cv::Mat1w& m) { return proto::rvl_ref_encode(m); },
          [](const Bytes& b, cv::Mat1w& out) {
            return proto::rvl_ref_decode(b, out.cols, out.rows, out) == proto::DecodeStatus::Ok;
          }};
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Thread CPU time: the machine is shared, and wall-clock medians would mostly measure the other
// processes; CPU time of this thread is what the codec itself costs.
double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

Measured measure(const Candidate& c, const cv::Mat1w& frame, int runs) {
  std::vector<double> enc, dec;
  Bytes bytes;
  bool lossless = true;
  cv::Mat1w out(frame.rows, frame.cols);
  for (int r = 0; r < runs; ++r) {
    out.setTo(0xBEEF);  // a stale decode must not pass as lossless
    const double t0 = thread_cpu_ms();
    bytes = c.encode(frame);
    const double t1 = thread_cpu_ms();
    const bool ok = c.decode(bytes, out);
    const double t2 = thread_cpu_ms();
    enc.push_back(t1 - t0);
    dec.push_back(t2 - t1);
    lossless = lossless && ok && cv::norm(frame, out, cv::NORM_INF) == 0.0;
  }
  return {c.name,
          c.ours,
          static_cast<double>(frame.total() * 2) / static_cast<double>(bytes.size()),
          median(enc),
          median(dec),
          lossless,
          bytes.size()};
}

cv::Mat1w load_frame(const std::string& path, const std::string& units) {
  cv::Mat1w depth_mm = telex::load_depth(path, telex::parse_depth_units(units)).depth_mm;
  // Codecs and peers read the pixels as one continuous buffer.
  return depth_mm.isContinuous() ? depth_mm : depth_mm.clone();
}

// Every codec measured, ours first; the names are what --only takes.
std::vector<Candidate> candidates(int zip_level) {
  return {
      ours(proto::Codec::Zip, zip_level),
      ours(proto::Codec::Fast, zip_level),
      tiled(proto::Codec::Zip, zip_level, 80, 60),
      tiled(proto::Codec::Fast, zip_level, 80, 60),
      zlib_peer(1),
      zlib_peer(6),
      zstd_peer(1),
      png_peer(3),
      rvl_peer(),
  };
}

std::vector<std::string> candidate_names() {
  std::vector<std::string> names;
  for (const auto& c : candidates(proto::kDefaultZipLevel)) names.push_back(c.name);
  return names;
}

const telex::tool::RegisterCommand kRegister{
    "codec", "Measure depth codecs (ours and peers) on one frame: ratio, speed, losslessness",
    [](cli::CommandLine& app) -> std::function<int()> {
      auto in = std::make_shared<std::string>();
      auto units = std::make_shared<std::string>("mm");
      auto json = std::make_shared<bool>(false);
      auto runs = std::make_shared<int>(9);
      auto level = std::make_shared<int>(proto::kDefaultZipLevel);
      app.add_option("--in", *in, "depth image (16-bit PNG, or PGM for kinect-disparity)")
          ->required();
      app.add_option("--units", *units, "depth units of the file: mm | tum | kinect-disparity")
          ->check(cli::IsMember({"mm", "tum", "kinect-disparity"}));
      app.add_flag("--json", *json, "print one JSON object {\"codecs\": [...]}");
      app.add_option("--runs", *runs, "repetitions; times are medians")->check(cli::Range(1, 1000));
      auto only = std::make_shared<std::vector<std::string>>();
      app.add_option("--only", *only, "measure only these codecs (default: all); repeatable")
          ->check(cli::IsMember(candidate_names()))
          ->delimiter(',');
      app.add_option("--zip-level", *level,
                     "deflate level of our zip codec (0 = Huffman-only, the default)")
          ->check(cli::Range(0, 9));
      return [=]() {
        const cv::Mat1w frame = load_frame(*in, *units);
        std::vector<Candidate> cands = candidates(*level);
        if (!only->empty())
          std::erase_if(cands, [&](const Candidate& c) {
            return std::find(only->begin(), only->end(), c.name) == only->end();
          });
        // One warm-up pass per codec so first-touch allocations do not skew the medians.
        for (const auto& c : cands) (void)measure(c, frame, 1);
        std::vector<Measured> results;
        for (const auto& c : cands) results.push_back(measure(c, frame, *runs));
        if (*json) {
          nlohmann::json j;
          j["file"] = *in;
          j["runs"] = *runs;
          j["width"] = frame.cols;
          j["height"] = frame.rows;
          j["codecs"] = nlohmann::json::array();
          for (const auto& m : results)
            j["codecs"].push_back({{"name", m.name},
                                   {"ours", m.ours},
                                   {"ratio", m.ratio},
                                   {"bytes", m.bytes},
                                   {"encode_ms", m.encode_ms},
                                   {"decode_ms", m.decode_ms},
                                   {"lossless", m.lossless}});
          std::cout << j.dump(2) << "\n";
        } else {
          std::cout << std::left << std::setw(18) << "codec" << std::setw(6) << "ours" << std::right
                    << std::setw(9) << "ratio" << std::setw(11) << "enc ms" << std::setw(11)
                    << "dec ms" << std::setw(10) << "lossless\n";
          for (const auto& m : results)
            std::cout << std::left << std::setw(18) << m.name << std::setw(6)
                      << (m.ours ? "yes" : "no") << std::right << std::fixed << std::setprecision(2)
                      << std::setw(9) << m.ratio << std::setprecision(3) << std::setw(11)
                      << m.encode_ms << std::setw(11) << m.decode_ms << std::setw(9)
                      << (m.lossless ? "true" : "false") << "\n";
        }
        bool all = true;
        for (const auto& m : results) all = all && m.lossless;
        return all ? 0 : 1;
      };
    }};

}  // namespace
}  // namespace telex::tool
