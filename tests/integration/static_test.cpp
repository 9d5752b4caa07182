// The web viewer's static files as wmd serves them.
#include <filesystem>
#include <fstream>

#include "e2e_fixture.h"

namespace wm::testing {
namespace {

class StaticFilesTest : public ServerFixture {
 protected:
  void SetUp() override {
    const auto web = dir_.path() / "web";
    std::filesystem::create_directories(web / "lib");
    std::ofstream(web / "index.html") << "<!doctype html><title>viewer</title>";
    std::ofstream(web / "lib" / "app.js") << "export const x = 1;";
    std::ofstream(web / ".secret") << "token";
    std::ofstream(dir_.path() / "outside.txt") << "not served";
    extra_args_ = {"--web", web.string()};
    ServerFixture::SetUp();
  }
};

TEST_F(StaticFilesTest, ServesTheViewerAndNothingElse) {
  auto r = call("GET", "/");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.body, "<!doctype html><title>viewer</title>");
  r = call("GET", "/web/lib/app.js");
  EXPECT_EQ(r.status, 200);
  EXPECT_EQ(r.body, "export const x = 1;");
  for (const std::string target : {"/web/../outside.txt", "/web/lib/../../outside.txt", "/web/%2e%2e/outside.txt",
                                   "/web/.secret", "/web/missing.js", "/web/", "/web//etc/passwd"}) {
    r = call("GET", target);
    EXPECT_EQ(r.status, 404) << target << ": " << r.body;
  }
  EXPECT_EQ(call("POST", "/web/lib/app.js", "{}").status, 405);
  EXPECT_EQ(get_json("/api/v1")["service"], "worldmodel");
}

}  // namespace
}  // namespace wm::testing
