// The web viewer's static files: index.html at "/", the rest under "/web/", from ApiOptions::web_dir.
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "server/api/api_error.h"
#include "server/api/handlers.h"
#include "server/api/response.h"

namespace wm::api {
namespace {

// The types the viewer uses; anything else is sent as bytes.
const std::string& content_type_of(const std::filesystem::path& file) {
  static const std::map<std::string, std::string> kTypes = {{".html", "text/html; charset=utf-8"},
                                                            {".js", "text/javascript; charset=utf-8"},
                                                            {".mjs", "text/javascript; charset=utf-8"},
                                                            {".css", "text/css; charset=utf-8"},
                                                            {".svg", "image/svg+xml"},
                                                            {".png", "image/png"},
                                                            {".json", "application/json"},
                                                            {".ico", "image/x-icon"}};
  static const std::string kBytes = "application/octet-stream";
  const auto type = kTypes.find(file.extension().string());
  return type == kTypes.end() ? kBytes : type->second;
}

// A file of the viewer. Paths are checked against the directory: no "..", no hidden files, no escape.
Response static_file(const Call& call, const std::string& relative) {
  if (call.options.web_dir.empty()) throw ApiError(404, "not_found", "this server has no web viewer (--web DIR)");
  if (relative.empty() || relative.find("..") != std::string::npos || relative.front() == '/' ||
      relative.find("/.") != std::string::npos || relative.front() == '.')
    throw ApiError(404, "not_found", "no file '" + relative + "'");
  const std::filesystem::path path = std::filesystem::path(call.options.web_dir) / relative;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw ApiError(404, "not_found", "no file '" + relative + "'");
  std::ifstream in(path, std::ios::binary);
  std::ostringstream content;
  content << in.rdbuf();
  auto response = raw_response(call.request, content.str(), content_type_of(path));
  response.set(boost::beast::http::field::cache_control, "no-cache");
  return response;
}

}  // namespace

Response get_static(const Call& call) { return static_file(call, call.param); }

Response get_root(const Call& call) {
  std::error_code no_index;
  if (!call.options.web_dir.empty() &&
      std::filesystem::is_regular_file(std::filesystem::path(call.options.web_dir) / "index.html", no_index))
    return static_file(call, "index.html");
  return get_index(call);
}

}  // namespace wm::api
