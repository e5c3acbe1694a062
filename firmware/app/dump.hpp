// Writer of the stage dump directory (docs/formats.md): inputs, labels, segment tables, every
// intermediate disparity map and meta.json. Used by `match --dump` and the link snapshot.
#pragma once
#include <string>

#include "fuzzystereo/fis.hpp"
#include "fuzzystereo/matcher.hpp"

namespace fs::app {

void write_match_dump(const std::string& dir, const std::string& left_name, const std::string& right_name,
                      const MatcherParams& params, const FisDefinition& fis, const ImageU8& left, const ImageU8& right,
                      const MatchResult& r);

}  // namespace fs::app
