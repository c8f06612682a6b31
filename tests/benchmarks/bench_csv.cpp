// What a number costs the recorder: rows of 10 floating-point cells written through
// record::CsvFile (committed every 16 rows, as a frame of 16 vehicles), against formatting the
// same numbers with fmt's "{:.9g}" into a buffer (how CsvFile formatted them before).
//
//   build/tests/benchmarks/bench_csv [ROWS]     (default 200000; numbers in docs/performance.md)
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <vector>

#include "record/run_files.hpp"

int main(int argc, char** argv) {
  const long rows = argc > 1 ? std::atol(argv[1]) : 200000;
  if (rows <= 0) {
    std::fprintf(stderr, "bench_csv: ROWS must be a positive number\n");
    return 1;
  }
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-200.0, 200.0);
  std::vector<double> values(static_cast<std::size_t>(rows) * 10);
  for (auto& v : values) v = (rng() % 5 == 0) ? u(rng) * 1e-4 : u(rng);  // poses, small rates

  const auto dir = std::filesystem::temp_directory_path() / "syndds-bench-csv";
  std::filesystem::create_directories(dir);
  using Clock = std::chrono::steady_clock;
  const auto per_number = [&](Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double, std::nano>(b - a).count() / values.size();
  };
  {
    syndds::record::CsvFile csv(dir / "bench.csv",
                                {"a", "b", "c", "d", "e", "f", "g", "h", "i", "j"});
    const auto t0 = Clock::now();
    for (long r = 0; r < rows; ++r) {
      const double* v = &values[static_cast<std::size_t>(r) * 10];
      csv.row(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8], v[9]);
      if (r % 16 == 15) csv.commit();
    }
    csv.commit();
    const auto t1 = Clock::now();
    std::printf("CsvFile: %.1f ns a number (%ld rows of 10, written to %s)\n", per_number(t0, t1),
                rows, (dir / "bench.csv").c_str());
  }
  fmt::memory_buffer buffer;
  std::size_t bytes = 0;
  const auto t0 = Clock::now();
  for (double v : values) {
    fmt::format_to(std::back_inserter(buffer), "{:.9g}", v);
    if (buffer.size() > 65536) {
      bytes += buffer.size();
      buffer.clear();
    }
  }
  const auto t1 = Clock::now();
  std::printf("fmt {:.9g} into a buffer: %.1f ns a number (%zu bytes)\n", per_number(t0, t1),
              bytes + buffer.size());
  std::filesystem::remove_all(dir);
  return 0;
}
