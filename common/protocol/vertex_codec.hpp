#pragma once
// Packed terrain vertices: the deformation lists every soft-soil vehicle sends every frame, in
// fewer bytes than 40 a vertex and exactly (every double comes back bit for bit). The records
// of a list are sorted by (i, j) and neighbours in a rut look alike, so each record is coded
// against the one before it:
//
//   count                      unsigned LEB128
//   per vertex:
//     i - i_prev, j - j_prev   zigzag LEB128 each (the first against (0, 0))
//     2 bytes                  four 4-bit lengths n (0-8), for height, level_initial,
//                              sinkage_plastic, sigma_yield (low nibble first)
//     per field: n bytes       the low n bytes (little endian) of bits(value) XOR
//                              bits(previous vertex's value), whose high bytes are zero
//
// A list that does not decode exactly (truncated, a length over 8, a varint over 10 bytes, an
// index outside int32, bytes left over, more vertices announced than bytes could hold) is
// refused with a ProtocolError naming the byte. docs/protocol.md, "Packed vertices".
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "protocol/messages.hpp"

namespace syndds::proto {

std::vector<std::uint8_t> pack_vertices(const std::vector<TerrainVertexMsg>& vertices);
/// pack_vertices(vertices).size(), without building the bytes (traffic accounting).
std::size_t packed_size(const std::vector<TerrainVertexMsg>& vertices);
std::vector<TerrainVertexMsg> unpack_vertices(std::span<const std::uint8_t> bytes);

}  // namespace syndds::proto
