// Constructors of the concrete readers behind openPointReader().
#pragma once

#include <filesystem>
#include <memory>

#include <tessera/lod/point_reader.h>

#include "byte_source.h"

namespace tessera::lod::detail {

std::unique_ptr<PointReader> openPly(ByteSource source);
std::unique_ptr<PointReader> openLas(ByteSource source);
std::unique_ptr<PointReader> openText(ByteSource source);
std::unique_ptr<PointReader> openObj(ByteSource source);
std::unique_ptr<PointReader> openStanfordConf(const std::filesystem::path& conf);

}  // namespace tessera::lod::detail
