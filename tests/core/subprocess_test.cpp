// core/subprocess.h: exit statuses, line-by-line stdout with deadlines, the stderr tail, and a
// timeout that kills the whole process group (what a hanging plug-in started dies with it).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <thread>

#include "core/errors.h"
#include "core/subprocess.h"
#include "core/timer.h"

namespace dnb {
namespace {
using ::testing::HasSubstr;

ProcessOptions sh(const std::string& script) { return ProcessOptions{.argv = {"/bin/sh", "-c", script}}; }

TEST(Subprocess, ReportsExitStatusesAndSignals) {
  Subprocess ok(sh("exit 0"));
  auto s = ok.wait(10);
  ASSERT_TRUE(s);
  EXPECT_TRUE(s->ok());
  Subprocess three(sh("exit 3"));
  s = three.wait(10);
  ASSERT_TRUE(s);
  EXPECT_FALSE(s->ok());
  EXPECT_EQ(s->describe(), "exited with status 3");
  Subprocess segv(sh("kill -SEGV $$"));
  s = segv.wait(10);
  ASSERT_TRUE(s);
  EXPECT_FALSE(s->exited);
  EXPECT_EQ(s->signal, SIGSEGV);
  EXPECT_THAT(s->describe(), HasSubstr("signal 11"));
}

TEST(Subprocess, KeepsTheLastLinesOfStderrAndForwardsEach) {
  std::vector<std::string> seen;
  ProcessOptions o = sh("for i in 1 2 3 4 5; do echo line$i >&2; done; printf partial >&2");
  o.tail_lines = 3;
  o.on_log_line = [&](const std::string& l) { seen.push_back(l); };
  Subprocess p(o);
  ASSERT_TRUE(p.wait(10));
  EXPECT_EQ(seen, (std::vector<std::string>{"line1", "line2", "line3", "line4", "line5", "partial"}));
  EXPECT_EQ(std::vector<std::string>(p.log_tail().begin(), p.log_tail().end()),
            (std::vector<std::string>{"line4", "line5", "partial"}));
}

TEST(Subprocess, TalksLineByLineOverStdinAndStdout) {
  ProcessOptions o = sh("echo ready; while read x; do echo \"got $x\"; done");
  o.pipe_stdin = o.pipe_stdout = true;
  Subprocess p(o);
  std::string line;
  ASSERT_EQ(p.read_line(line, 10), Subprocess::Read::Line);
  EXPECT_EQ(line, "ready");
  for (const char* w : {"a", "b c"}) {
    ASSERT_TRUE(p.write_line(w));
    ASSERT_EQ(p.read_line(line, 10), Subprocess::Read::Line);
    EXPECT_EQ(line, std::string("got ") + w);
  }
  p.close_stdin();
  EXPECT_EQ(p.read_line(line, 10), Subprocess::Read::Eof);
  auto s = p.wait(10);
  ASSERT_TRUE(s);
  EXPECT_TRUE(s->ok());
}

TEST(Subprocess, ATimeoutReturnsOnTimeAndKillingTheGroupEndsItsChildren) {
  // The shell starts a background child that would outlive it; both are in its process group.
  ProcessOptions o = sh("sleep 617.5 & echo started; wait");
  o.pipe_stdout = true;
  Subprocess p(o);
  std::string line;
  ASSERT_EQ(p.read_line(line, 10), Subprocess::Read::Line);
  Stopwatch sw;
  EXPECT_EQ(p.read_line(line, 0.3), Subprocess::Read::Timeout);
  EXPECT_FALSE(p.wait(0.2));
  // Generous upper bound: the two waits asked for 0.5 s; a loaded 2-core machine may add some.
  EXPECT_LT(sw.seconds(), 3.0);
  const ExitStatus s = p.kill_group();
  EXPECT_EQ(s.signal, SIGKILL);
  // The group's other member is gone (pgrep exits 1 when nothing matches).
  for (int i = 0; i < 50 && std::system("pgrep -f 'sleep 61[7].5' >/dev/null") == 0; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_NE(std::system("pgrep -f 'sleep 61[7].5' >/dev/null"), 0);
}

TEST(Subprocess, AProgramThatCannotStartIsAWorkErrorNamingIt) {
  try {
    Subprocess p(ProcessOptions{.argv = {"/no/such/program"}});
    FAIL() << "started";
  } catch (const WorkError& e) {
    EXPECT_THAT(e.what(), HasSubstr("/no/such/program"));
    EXPECT_THAT(e.what(), HasSubstr("No such file"));
  }
}

}  // namespace
}  // namespace dnb
