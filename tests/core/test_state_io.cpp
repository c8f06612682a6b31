// Checkpoint state encoding: exact round trips, sections that catch a reader disagreeing with
// its writer, and files that refuse damage.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/state_io.hpp"

namespace syndds::core {
namespace {

struct Pid {
  double integral = 0.0;
  std::vector<double> history;
  template <typename A>
  void state(A& a) {
    a.begin("pid", 2);
    a.io(integral);
    a.io(history);
    a.end();
  }
  void state(StateWriter& w) const { const_cast<Pid*>(this)->state<StateWriter>(w); }
};

TEST(StateIo, NumbersStringsListsAndEigenComeBackBitForBit) {
  StateWriter w;
  const double tiny = std::numeric_limits<double>::denorm_min();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  w.io(0.1);
  w.io(-0.0);
  w.io(tiny);
  w.io(nan);
  w.io(std::int64_t{-5});
  w.io(true);
  w.io(std::string("ab\0c", 4));
  w.io(std::vector<float>{1.5f, -2.25f});
  w.io(std::vector<std::string>{"x", ""});
  w.io(Eigen::Vector3d(1.0 / 3.0, 2, 3));
  w.io(Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5));

  StateReader r(w.bytes(), "test");
  EXPECT_EQ(r.get<double>(), 0.1);
  const double neg_zero = r.get<double>();
  EXPECT_TRUE(std::signbit(neg_zero));
  EXPECT_EQ(r.get<double>(), tiny);
  EXPECT_TRUE(std::isnan(r.get<double>()));
  EXPECT_EQ(r.get<std::int64_t>(), -5);
  EXPECT_TRUE(r.get<bool>());
  EXPECT_EQ(r.get<std::string>(), std::string("ab\0c", 4));
  EXPECT_EQ(r.get<std::vector<float>>(), (std::vector<float>{1.5f, -2.25f}));
  EXPECT_EQ(r.get<std::vector<std::string>>(), (std::vector<std::string>{"x", ""}));
  Eigen::Vector3d v;
  r.io(v);
  EXPECT_EQ(v, Eigen::Vector3d(1.0 / 3.0, 2, 3));
  Eigen::Quaterniond q;
  r.io(q);
  EXPECT_EQ(q.coeffs(), Eigen::Quaterniond(0.5, 0.5, -0.5, 0.5).coeffs());
  EXPECT_TRUE(r.at_end());
}

TEST(StateIo, OneTemplateSavesAndLoadsAComponent) {
  Pid a{1.25, {1, 2, 3}};
  StateWriter w;
  w.io(a);
  Pid b;
  StateReader r(w.bytes(), "pid.state");
  r.io(b);
  EXPECT_EQ(b.integral, 1.25);
  EXPECT_EQ(b.history, a.history);
}

TEST(StateIo, AReaderOfAnotherSectionOrVersionIsToldWhich) {
  StateWriter w;
  w.begin("vehicle", 3);
  w.io(1.0);
  w.end();
  {
    StateReader r(w.bytes(), "v.state");
    try {
      r.begin("soil", 1);
      FAIL();
    } catch (const StateError& e) {
      EXPECT_NE(std::string(e.what()).find("expected section 'soil', found 'vehicle'"),
                std::string::npos)
          << e.what();
      EXPECT_NE(std::string(e.what()).find("v.state"), std::string::npos);
    }
  }
  {
    StateReader r(w.bytes(), "v.state");
    try {
      r.begin("vehicle", 2, 1);
      FAIL();
    } catch (const StateError& e) {
      EXPECT_NE(std::string(e.what()).find("format version 3; this build reads versions 1 to 2"),
                std::string::npos)
          << e.what();
    }
  }
}

TEST(StateIo, ReadingPastOrShortOfASectionsEndFailsAtThatSection) {
  StateWriter w;
  w.begin("outer", 1);
  w.begin("inner", 1);
  w.io(std::int32_t{7});
  w.end();
  w.io(2.0);
  w.end();
  {
    StateReader r(w.bytes(), "f");
    r.begin("outer", 1);
    r.begin("inner", 1);
    EXPECT_THROW(r.get<std::int64_t>(), StateError);  // 8 bytes wanted, 4 in the section
  }
  {
    StateReader r(w.bytes(), "f");
    r.begin("outer", 1);
    r.begin("inner", 1);
    try {
      r.end();  // the int was not read
      FAIL();
    } catch (const StateError& e) {
      EXPECT_NE(std::string(e.what()).find("section 'outer': section 'inner': 4 bytes"),
                std::string::npos)
          << e.what();
    }
  }
  {
    StateReader r(w.bytes(), "f");
    r.begin("outer", 1);
    r.begin("inner", 1);
    EXPECT_EQ(r.get<std::int32_t>(), 7);
    r.end();
    EXPECT_EQ(r.get<double>(), 2.0);
    r.end();
    EXPECT_TRUE(r.at_end());
  }
}

TEST(StateIo, AFramedFileRefusesTruncationAndDamage) {
  StateWriter w;
  w.io(std::string("state of a member"));
  const std::string framed = frame_state(w.bytes());
  EXPECT_EQ(unframe_state(framed, "m.state"), w.bytes());
  try {
    unframe_state(framed.substr(0, framed.size() - 1), "m.state");
    FAIL();
  } catch (const StateError& e) {
    EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
  }
  std::string damaged = framed;
  damaged.back() ^= 1;
  try {
    unframe_state(damaged, "m.state");
    FAIL();
  } catch (const StateError& e) {
    EXPECT_NE(std::string(e.what()).find("m.state: checksum"), std::string::npos) << e.what();
  }
  EXPECT_THROW(unframe_state("hello", "x"), StateError);
}

TEST(StateIo, AHugeCountIsRefusedInsteadOfAllocated) {
  StateWriter w;
  w.io(std::uint64_t{1} << 60);
  StateReader r(w.bytes(), "f");
  EXPECT_THROW(r.get<std::vector<double>>(), StateError);
}

}  // namespace
}  // namespace syndds::core
