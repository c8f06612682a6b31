// Packed terrain vertices (protocol/vertex_codec.hpp): every record comes back bit for bit,
// whatever its values (signed zeros, NaN payloads, infinities, denormals, extreme indices), in
// any order; damaged lists are refused, never half-read.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "core/error.hpp"
#include "protocol/vertex_codec.hpp"

using namespace syndds;
using proto::TerrainVertexMsg;

namespace {

bool bit_equal(const std::vector<TerrainVertexMsg>& a, const std::vector<TerrainVertexMsg>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t k = 0; k < a.size(); ++k) {
    const double x[4] = {a[k].height, a[k].level_initial, a[k].sinkage_plastic, a[k].sigma_yield};
    const double y[4] = {b[k].height, b[k].level_initial, b[k].sinkage_plastic, b[k].sigma_yield};
    if (a[k].i != b[k].i || a[k].j != b[k].j || std::memcmp(x, y, sizeof x) != 0) return false;
  }
  return true;
}

}  // namespace

TEST(VertexCodec, EveryValueComesBackBitForBit) {
  const double nan_payload = std::bit_cast<double>(std::uint64_t{0x7ff8000000001234});
  const double specials[] = {0.0, -0.0, std::numeric_limits<double>::infinity(),
                             -std::numeric_limits<double>::infinity(), nan_payload,
                             std::numeric_limits<double>::denorm_min(),
                             std::numeric_limits<double>::max(), -1e-300, 1e4};
  std::vector<TerrainVertexMsg> list;
  const std::int32_t lo = std::numeric_limits<std::int32_t>::min();
  const std::int32_t hi = std::numeric_limits<std::int32_t>::max();
  for (std::int32_t i : {lo, -1, 0, 7, hi}) {
    for (double s : specials) list.push_back({i, hi - (i & 0xff), s, -s, s * 0.5, 1e4 + s});
  }
  std::mt19937_64 rng(7);
  std::uniform_int_distribution<std::int32_t> index(lo, hi);
  for (int k = 0; k < 500; ++k) {  // unsorted and far apart: deltas of every size
    list.push_back({index(rng), index(rng), std::bit_cast<double>(rng()),
                    std::bit_cast<double>(rng()), std::bit_cast<double>(rng()),
                    std::bit_cast<double>(rng())});
  }
  EXPECT_TRUE(bit_equal(proto::unpack_vertices(proto::pack_vertices(list)), list));
  EXPECT_EQ(proto::packed_size(list), proto::pack_vertices(list).size());
  EXPECT_TRUE(proto::unpack_vertices(proto::pack_vertices({})).empty());
  EXPECT_EQ(proto::pack_vertices({}).size(), 1u);
}

// A rut as SCM writes it: neighbouring vertices along j, levels and stresses that differ a
// little from one to the next, an undisturbed initial level. Well under 40 bytes a vertex.
TEST(VertexCodec, ARutPacksIntoFewerBytesThanStructRecords) {
  std::vector<TerrainVertexMsg> rut;
  for (std::int32_t i = 100; i < 110; ++i) {
    for (std::int32_t j = -20; j < 20; ++j) {
      const double sink = 0.03 * std::exp(-0.01 * j * j) + 1e-4 * (i - 100);
      rut.push_back({i, j, -sink, 0.0, 0.8 * sink, 2e4 + 1e5 * sink});
    }
  }
  const auto packed = proto::pack_vertices(rut);
  EXPECT_EQ(proto::packed_size(rut), packed.size());
  EXPECT_TRUE(bit_equal(proto::unpack_vertices(packed), rut));
  EXPECT_LT(static_cast<double>(packed.size()) / static_cast<double>(rut.size()), 26.0);
}

TEST(VertexCodec, DamagedListsAreRefusedNamingTheByte) {
  const std::vector<TerrainVertexMsg> list = {{3, 4, -0.01, 0.0, 0.01, 1e4},
                                              {3, 5, -0.02, 0.0, 0.02, 2e4}};
  const auto good = proto::pack_vertices(list);
  auto error = [](std::vector<std::uint8_t> bytes) -> std::string {
    try {
      proto::unpack_vertices(bytes);
    } catch (const ProtocolError& e) {
      return e.what();
    }
    return "(accepted)";
  };
  // Every truncation is refused.
  for (std::size_t n = 0; n < good.size(); ++n) {
    const std::string e = error(std::vector<std::uint8_t>(good.begin(), good.begin() + n));
    EXPECT_EQ(e.rfind("packed vertices: ", 0), 0u) << n << ": " << e;
  }
  auto longer = good;
  longer.push_back(0);
  EXPECT_EQ(error(longer), "packed vertices: 1 bytes after the last vertex at byte " +
                               std::to_string(good.size()) + " of " +
                               std::to_string(good.size() + 1));
  // A varint that never ends, and one beyond 64 bits.
  EXPECT_EQ(error(std::vector<std::uint8_t>(11, 0xff)).rfind("packed vertices: varint", 0), 0u);
  std::vector<std::uint8_t> wide(9, 0x80);
  wide.push_back(0x02);
  EXPECT_EQ(error(wide), "packed vertices: varint overflows 64 bits at byte 10 of 10");
  // An index delta that leaves int32: the second vertex's i delta -1 (zigzag 1) becomes +1.
  const std::int32_t top = std::numeric_limits<std::int32_t>::max();
  auto beyond = proto::pack_vertices({{top, 0, 0, 0, 0, 0}, {top - 1, 0, 0, 0, 0, 0}});
  // count (1 byte), i (5), j (1), lengths (2, all zero): the second vertex starts at byte 9.
  ASSERT_EQ(beyond.size(), 13u);
  ASSERT_EQ(beyond[9], 0x01);
  beyond[9] = 0x02;
  EXPECT_EQ(error(beyond), "packed vertices: vertex index i outside int32 at byte 10 of 13")
      << error(beyond);
}
