// SPDX-License-Identifier: MIT
// libFuzzer target: a ROS 1 bag as the bag source and `telex replay` read one: the input is the
// file. rosbag_storage parses the container; the adapter decodes every message (images with any
// width, height, step and encoding). A malformed file must end in an exception, never a crash.
#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <exception>
#include <string>

#include "telex/bag/bag.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // rosbag opens a path: a memory file, reached through /proc.
  static const int fd = memfd_create("bag_fuzz", 0);
  if (fd < 0) __builtin_trap();
  if (ftruncate(fd, 0) != 0 || pwrite(fd, data, size, 0) != static_cast<ssize_t>(size))
    __builtin_trap();
  const std::string path = "/proc/self/fd/" + std::to_string(fd);
  try {
    telex::bag::Reader reader(path);
    (void)reader.describe_topics();
    telex::bag::Message m;
    std::size_t n = 0;
    while (reader.next(m) && ++n < 10'000) {
      if (!m.image.empty() && m.image.total() * m.image.elemSize() > (std::size_t{1} << 31))
        __builtin_trap();  // the decoded image is bounded by the bytes the message held
    }
  } catch (const std::exception&) {
    // A clear error is the expected outcome for a malformed file.
  }
  return 0;
}
