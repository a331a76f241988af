// SPDX-License-Identifier: Apache-2.0
//
// Small file helpers shared by the map and model writers.
#pragma once

#include <string>
#include <string_view>

namespace neuralyarn {

/* Current UTC time, ISO 8601 ("2026-11-22T10:00:00Z"). */
std::string utc_now();

/* Writes `head` then `body` to a temporary file beside `path` and renames it into place, so an existing
 * file is only ever replaced by a complete new one. Throws std::runtime_error with a message that does
 * not repeat the path (callers prefix it). */
void write_file_atomically(const std::string &path, std::string_view head, std::string_view body);

/* The whole file; throws std::runtime_error ("cannot open: <reason>"). */
std::string read_file(const std::string &path);

}  // namespace neuralyarn
