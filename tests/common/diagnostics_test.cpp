// Diagnostics: counts by where and severity, the bounded list of recent reports, the echo, and reports from several
// threads at once.
#include "common/diagnostics.h"

#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace wm::common {
namespace {

TEST(DiagnosticsTest, CountsEachReportByWhereAndSeverity) {
  Diagnostics diagnostics("", nullptr);
  diagnostics.report(Severity::warning, "grid", "flush failed");
  diagnostics.report(Severity::warning, "grid", "flush failed again");
  diagnostics.report(Severity::error, "grid", "scan 3 not inserted");
  diagnostics.report(Severity::info, "rules", "rules reloaded");
  const auto summary = diagnostics.summary();
  EXPECT_EQ(summary.total.warnings, 2u);
  EXPECT_EQ(summary.total.errors, 1u);
  EXPECT_EQ(summary.total.info, 1u);
  ASSERT_EQ(summary.by_where.size(), 2u);
  EXPECT_EQ(summary.by_where.at("grid").warnings, 2u);
  EXPECT_EQ(summary.by_where.at("grid").errors, 1u);
  EXPECT_EQ(summary.by_where.at("grid").info, 0u);
  EXPECT_EQ(summary.by_where.at("rules").info, 1u);
  ASSERT_EQ(summary.recent.size(), 4u);
  EXPECT_EQ(summary.recent[2].severity, Severity::error);
  EXPECT_EQ(summary.recent[2].where, "grid");
  EXPECT_EQ(summary.recent[2].message, "scan 3 not inserted");
  EXPECT_GT(summary.recent[2].at_unix_s, 1.6e9);
  EXPECT_LE(summary.recent[2].at_unix_s, summary.recent[3].at_unix_s);
}

TEST(DiagnosticsTest, KeepsOnlyTheLastReportsButCountsThemAll) {
  Diagnostics diagnostics("", nullptr, 3);
  for (int i = 0; i < 10; ++i) diagnostics.report(Severity::warning, "grid", "report " + std::to_string(i));
  const auto summary = diagnostics.summary();
  EXPECT_EQ(summary.total.warnings, 10u);
  ASSERT_EQ(summary.recent.size(), 3u);
  EXPECT_EQ(summary.recent[0].message, "report 7");  // oldest first
  EXPECT_EQ(summary.recent[2].message, "report 9");
}

TEST(DiagnosticsTest, AKeptMessageIsCutButTheEchoHasItWhole) {
  std::ostringstream echo;
  Diagnostics diagnostics("wmd: ", &echo);
  const std::string long_message(Diagnostics::kMaxKeptMessageBytes * 3, 'x');
  diagnostics.report(Severity::error, "rules", long_message);
  EXPECT_EQ(echo.str(), "wmd: " + long_message + "\n");
  const auto summary = diagnostics.summary();
  ASSERT_EQ(summary.recent.size(), 1u);
  EXPECT_LE(summary.recent[0].message.size(), Diagnostics::kMaxKeptMessageBytes + 3);
  EXPECT_EQ(summary.recent[0].message.substr(0, 10), "xxxxxxxxxx");
}

TEST(DiagnosticsTest, EchoesEveryReportAsOneLineWithThePrefix) {
  std::ostringstream echo;
  Diagnostics diagnostics("wmd: ", &echo);
  diagnostics.report(Severity::info, "rules", "rules reloaded (generation 2, 1 files)");
  diagnostics.report(Severity::warning, "rules", "rules edit rejected, the previous rules stay active:\nx.pl:1: oops");
  EXPECT_EQ(echo.str(),
            "wmd: rules reloaded (generation 2, 1 files)\n"
            "wmd: rules edit rejected, the previous rules stay active:\nx.pl:1: oops\n");
}

TEST(DiagnosticsTest, ReportsFromSeveralThreadsAreAllCountedAndTheirLinesStayWhole) {
  std::ostringstream echo;
  Diagnostics diagnostics("", &echo, 50);
  constexpr int kThreads = 4;
  constexpr int kReports = 2000;
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&diagnostics, t] {
      const std::string where = "thread" + std::to_string(t);
      for (int i = 0; i < kReports; ++i) {
        diagnostics.report(i % 2 == 0 ? Severity::warning : Severity::error, where, where + " line");
        if (i % 100 == 0) (void)diagnostics.summary();  // readers meanwhile
      }
    });
  }
  for (auto& thread : threads) thread.join();
  const auto summary = diagnostics.summary();
  EXPECT_EQ(summary.total.warnings, kThreads * kReports / 2u);
  EXPECT_EQ(summary.total.errors, kThreads * kReports / 2u);
  ASSERT_EQ(summary.by_where.size(), static_cast<std::size_t>(kThreads));
  for (const auto& [where, counts] : summary.by_where) EXPECT_EQ(counts.warnings + counts.errors, kReports + 0u);
  EXPECT_EQ(summary.recent.size(), 50u);
  std::istringstream lines(echo.str());
  std::size_t count = 0;
  for (std::string line; std::getline(lines, line); ++count)
    ASSERT_TRUE(line.size() == std::string("thread0 line").size() && line.ends_with(" line")) << line;
  EXPECT_EQ(count, static_cast<std::size_t>(kThreads * kReports));
}

TEST(DiagnosticsTest, SeverityNames) {
  EXPECT_EQ(severity_name(Severity::info), "info");
  EXPECT_EQ(severity_name(Severity::warning), "warning");
  EXPECT_EQ(severity_name(Severity::error), "error");
}

}  // namespace
}  // namespace wm::common
