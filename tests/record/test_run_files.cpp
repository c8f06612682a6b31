// The run-directory writer: column lists, escaping, checked writes, frames that are all or
// nothing, atomic replacement.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "record/run_files.hpp"
#include "record_test_util.hpp"

using namespace syndds::record;
namespace fs = std::filesystem;

using syndds::test::FileSizeLimit;
using syndds::test::read_file;

namespace {

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::path(testing::TempDir()) / ("syndds-run-files-" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

}  // namespace

TEST(RunFiles, HeaderAndRowsComeFromOneColumnList) {
  const fs::path dir = fresh_dir("header");
  CsvFile csv(dir / "t.csv", {"frame", "time_s", "vehicle", "x"});
  csv.row(std::int64_t{3}, 0.03, std::string("v1"), Fixed{1.5, 4});
  csv.row(4, Sig{0.123456789, 3}, "v2", 2.0);
  csv.commit();
  EXPECT_EQ(read_file(dir / "t.csv"), "frame,time_s,vehicle,x\n3,0.03,v1,1.5000\n4,0.123,v2,2\n");
}

// Numbers read as C's printf writes them ("%.9g", "%.*g", "%.*f"), the text every run so far
// has recorded: special values, the longest fixed text, and random bit patterns.
TEST(RunFiles, NumbersAreWrittenAsPrintfWritesThem) {
  const fs::path dir = fresh_dir("numbers");
  std::vector<double> values = {0.0, -0.0, 0.5, 2.5, 1e9, 999999999.5, 1e-5, 1e16, 1e-300, 5e-324,
                                1e300, -1.7976931348623157e308, INFINITY, -INFINITY, NAN};
  std::mt19937_64 bits(7);
  for (int k = 0; k < 2000; ++k) {
    std::uint64_t b = bits();
    double v;
    std::memcpy(&v, &b, sizeof v);
    if (!std::isnan(v)) values.push_back(v);
    values.push_back(std::ldexp(static_cast<double>(b % 100000000) / 1e3, -static_cast<int>(b % 30)));
  }
  CsvFile csv(dir / "n.csv", {"g9", "g4", "f3", "f9", "float"});
  std::string expected = "g9,g4,f3,f9,float\n";
  char text[4096];  // two fixed texts of 1e308
  for (double v : values) {
    const float f = static_cast<float>(v);
    csv.row(v, Sig{v, 4}, Fixed{v, 3}, Fixed{v, 9}, f);
    std::snprintf(text, sizeof text, "%.9g,%.4g,%.3f,%.9f,%.9g\n", v, v, v, v,
                  static_cast<double>(f));
    expected += text;
  }
  csv.commit();
  EXPECT_EQ(read_file(dir / "n.csv"), expected);
}

TEST(RunFiles, ARowOfTheWrongArityIsAProgrammingError) {
  const fs::path dir = fresh_dir("arity");
  CsvFile csv(dir / "t.csv", {"a", "b", "c"});
  try {
    csv.row(1, 2);
    FAIL() << "a row of 2 cells for 3 columns was accepted";
  } catch (const std::logic_error& e) {
    EXPECT_NE(std::string(e.what()).find("t.csv"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("2 cells for 3 columns"), std::string::npos) << e.what();
  }
  EXPECT_THROW(csv.row(1, 2, 3, 4), std::logic_error);
  csv.commit();
  EXPECT_EQ(read_file(dir / "t.csv"), "a,b,c\n");
}

TEST(RunFiles, TextCellsAreQuotedAsRfc4180Asks) {
  EXPECT_EQ(csv_escape("plain id"), "plain id");
  EXPECT_EQ(csv_escape("a,b"), "\"a,b\"");
  EXPECT_EQ(csv_escape("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(csv_escape("two\nlines"), "\"two\nlines\"");
  EXPECT_EQ(csv_escape("cr\r"), "\"cr\r\"");
  const fs::path dir = fresh_dir("escape");
  CsvFile csv(dir / "t.csv", {"id", "n"});
  csv.row("cam,front", 1);
  csv.commit();
  EXPECT_EQ(read_file(dir / "t.csv"), "id,n\n\"cam,front\",1\n");
}

TEST(RunFiles, AFullDiskIsAnErrorNamingTheFile) {
  // /dev/full refuses every write with ENOSPC, as a full disk does.
  try {
    CsvFile csv("/dev/full", {"a"});
    FAIL() << "writing the header to /dev/full did not fail";
  } catch (const WriteError& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/full"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("No space left on device"), std::string::npos)
        << e.what();
  }
  OutputFile raw("/dev/full");
  EXPECT_THROW(raw.write("x"), WriteError);
}

TEST(RunFiles, AFailedFrameLeavesNoPartOfItInAnyFile) {
  const fs::path dir = fresh_dir("rollback");
  CsvFile a(dir / "a.csv", {"frame", "text"});
  CsvFile b(dir / "b.csv", {"frame", "text"});
  a.row(0, "first");
  b.row(0, "first");
  commit_rows({&a, &b});
  const std::string a0 = read_file(dir / "a.csv"), b0 = read_file(dir / "b.csv");
  {
    FileSizeLimit limit(static_cast<rlim_t>(a0.size() + 10));
    a.row(1, "second row, fits");  // longer than 10 bytes: written in part, then EFBIG
    b.row(1, "second");
    try {
      commit_rows({&a, &b});
      FAIL() << "a write past the file size limit succeeded";
    } catch (const WriteError& e) {
      EXPECT_NE(std::string(e.what()).find("a.csv"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("large"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(read_file(dir / "a.csv"), a0);
  EXPECT_EQ(read_file(dir / "b.csv"), b0);
  // The files go on from there (nothing of the failed frame is left in the buffers).
  a.row(2, "third");
  commit_rows({&a, &b});
  EXPECT_EQ(read_file(dir / "a.csv"), a0 + "2,third\n");
  EXPECT_EQ(read_file(dir / "b.csv"), b0);
}

TEST(RunFiles, AtomicReplacementLeavesTheOldFileWhenTheNewOneCannotBeWritten) {
  const fs::path dir = fresh_dir("atomic");
  write_file_atomically(dir / "s.json", "{\"old\": 1}\n");
  EXPECT_EQ(read_file(dir / "s.json"), "{\"old\": 1}\n");
  {
    FileSizeLimit limit(16);
    EXPECT_THROW(write_file_atomically(dir / "s.json", std::string(100, 'x')), WriteError);
  }
  EXPECT_EQ(read_file(dir / "s.json"), "{\"old\": 1}\n");
  EXPECT_FALSE(fs::exists(dir / "s.json.tmp"));
  write_file_atomically(dir / "s.json", "new\n");
  EXPECT_EQ(read_file(dir / "s.json"), "new\n");
  EXPECT_THROW(write_file_atomically(dir / "missing" / "s.json", "x"), WriteError);
}

TEST(RunFiles, ASpaceReserveHoldsItsBytesUntilReleased) {
  const fs::path dir = fresh_dir("reserve");
  {
    SpaceReserve reserve(dir / ".reserve", 64 * 1024);
    ASSERT_TRUE(fs::exists(dir / ".reserve"));
    EXPECT_EQ(fs::file_size(dir / ".reserve"), 64u * 1024u);
    reserve.release();
    EXPECT_FALSE(fs::exists(dir / ".reserve"));
    reserve.release();  // twice is fine
  }
  { SpaceReserve reserve(dir / ".reserve", 1024); }
  EXPECT_FALSE(fs::exists(dir / ".reserve"));  // released when destroyed
  try {
    FileSizeLimit limit(1000);
    SpaceReserve too_big(dir / ".reserve", 4096);
    FAIL() << "a reserve past the file size limit was allocated";
  } catch (const WriteError& e) {
    EXPECT_NE(std::string(e.what()).find(".reserve: cannot reserve 4096 bytes"), std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(fs::exists(dir / ".reserve"));
}
