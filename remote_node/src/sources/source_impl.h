// SPDX-License-Identifier: MIT
// Internal: constructors of the concrete sources, used by the spec factories and the tests.
#pragma once

#include <memory>

#include "telex/remote/sources.h"

namespace telex::remote::detail {

std::unique_ptr<DepthSource> make_openni_source(const SourceSpec& spec,
                                                const SourceOptions& options);
std::unique_ptr<DepthSource> make_freenect_source(const SourceSpec& spec,
                                                  const SourceOptions& options);
std::unique_ptr<DepthSource> make_oni_source(const SourceSpec& spec, const SourceOptions& options);
std::unique_ptr<DepthSource> make_files_depth_source(const SourceSpec& spec,
                                                     const SourceOptions& options);
std::unique_ptr<DepthSource> make_bag_depth_source(const SourceSpec& spec,
                                                   const SourceOptions& options);
std::unique_ptr<StereoSource> make_bag_colour_source(const SourceSpec& spec,
                                                     const SourceOptions& options);
std::unique_ptr<DepthSource> make_synthetic_depth_source(const SourceSpec& spec,
                                                         const SourceOptions& options);
std::unique_ptr<StereoSource> make_v4l2_stereo_source(const SourceSpec& spec,
                                                      const SourceOptions& options);
std::unique_ptr<StereoSource> make_files_stereo_source(const SourceSpec& spec,
                                                       const SourceOptions& options);
std::unique_ptr<StereoSource> make_synthetic_stereo_source(const SourceSpec& spec,
                                                           const SourceOptions& options);

// Throws std::invalid_argument when `spec` carries an option outside `allowed`.
void require_options(const SourceSpec& spec, std::initializer_list<std::string_view> allowed);

}  // namespace telex::remote::detail
