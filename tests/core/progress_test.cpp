// core/progress.h from several threads: every add() counts, lines are printed while workers
// add, and nothing races (this test is in the ThreadSanitizer run, scripts/test-sanitizers
// --thread: the time of the last line was read without the lock while another thread wrote it).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <memory>
#include <sstream>
#include <thread>
#include <vector>

#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include "core/progress.h"

namespace dnb {
namespace {

TEST(Progress, CountsEveryAddFromManyThreadsAndPrintsWhileTheyRun) {
  std::ostringstream log;
  auto previous = spdlog::default_logger();
  auto logger = std::make_shared<spdlog::logger>("progress-test", std::make_shared<spdlog::sinks::ostream_sink_mt>(log));
  logger->set_pattern("%v");
  spdlog::set_default_logger(logger);
  {
    // An interval of 0: every add() may print, so the threads contend for the line all the time.
    Progress p("test", 4 * 500, "steps", 0.0);
    std::vector<std::thread> threads;
    for (int t = 0; t < 4; ++t)
      threads.emplace_back([&p] {
        for (int i = 0; i < 500; ++i) p.add(1);
      });
    for (auto& th : threads) th.join();
    p.finish();
  }
  spdlog::set_default_logger(previous);
  const std::string text = log.str();
  EXPECT_THAT(text, ::testing::HasSubstr("test: done, 2000 steps"));
  EXPECT_THAT(text, ::testing::HasSubstr("/2000 steps"));  // progress lines while running
}

}  // namespace
}  // namespace dnb
