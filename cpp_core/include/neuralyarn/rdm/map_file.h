// SPDX-License-Identifier: Apache-2.0
//
// The RDM file (".nyrdm"), documented in docs/file_formats.md:
//
//   bytes 0..7    magic "NYRDM\r\n\x1a" (the PNG trick: text-mode and truncation damage show at once)
//   bytes 8..11   format version, uint32 little endian (this code writes and reads version 1)
//   bytes 12..19  header length H, uint64 little endian
//   bytes 20..    header: H bytes of UTF-8 JSON (parameters, seed, paths, code version, summary, and the
//                 list of arrays with dtype, shape, byte offset and byte length within the payload)
//   then          payload: the arrays back to back, little endian, each 64-byte aligned within the payload
//
// The header carries the payload's FNV-1a 64 hash, so truncation and bit rot are detected on load.
// Files are written to "<path>.tmp-<pid>" and renamed over <path> only when complete.
#pragma once

#include <stdexcept>
#include <string>

#include "neuralyarn/rdm/gather.h"

namespace neuralyarn::rdm {

/* Version 1: a ply's maps; version 2: a yarn's (the header's "structure"), which builds that read only
 * version 1 refuse instead of taking them for a ply's. */
constexpr uint32_t kMapFileVersion = 1;
constexpr uint32_t kMapFileVersionYarn = 2;

class MapFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/* Writes the maps (and their standard errors, if present). Throws MapFileError naming the path when it
 * cannot be written; an existing file at `path` is only replaced by a complete new one. */
void save_maps(const RdmMaps &maps, const std::string &path);

/* Reads and validates a map file: magic, version, header keys, array shapes against the bins, payload
 * size and hash, finite non-negative values. Throws MapFileError saying what is wrong. */
RdmMaps load_maps(const std::string &path);

}  // namespace neuralyarn::rdm
