#pragma once
// wmd as a child process for the end-to-end benches, and one keep-alive HTTP/1.1 connection to it. The bench
// target defines WM_WMD (the wmd binary's path).
#include <fcntl.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#ifndef WM_WMD
#error "benches using bench/support/wmd_child.h define WM_WMD"
#endif

namespace wm::bench {

namespace beast = boost::beast;
namespace http = boost::beast::http;
namespace net = boost::asio;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// A fresh directory, removed with everything in it.
class TempDir {
 public:
  TempDir() {
    std::string pattern = (fs::temp_directory_path() / "wm-bench-XXXXXX").string();
    if (!::mkdtemp(pattern.data())) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ignored;
    fs::remove_all(path_, ignored);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

// One keep-alive HTTP/1.1 connection to wmd on loopback.
class Connection {
 public:
  explicit Connection(unsigned short port) : endpoint_(net::ip::make_address("127.0.0.1"), port) { connect(); }

  struct Answer {
    int status;
    std::string body;
  };

  Answer request(http::verb verb, const std::string& target, const std::string& body = {}) {
    http::request<http::string_body> req{verb, target, 11};
    req.set(http::field::host, "127.0.0.1");
    req.keep_alive(true);
    if (!body.empty()) {
      req.set(http::field::content_type, "application/json");
      req.body() = body;
    }
    req.prepare_payload();
    stream_.expires_after(std::chrono::seconds(60));
    http::write(stream_, req);
    http::response<http::string_body> res;
    http::read(stream_, buffer_, res);
    if (!res.keep_alive()) reconnect();  // the server may close after an error answer
    return {static_cast<int>(res.result_int()), std::move(res.body())};
  }

 private:
  void connect() {
    stream_.expires_after(std::chrono::seconds(10));
    stream_.connect(endpoint_);
    stream_.socket().set_option(net::ip::tcp::no_delay(true));
  }
  void reconnect() {
    beast::error_code ignored;
    stream_.socket().shutdown(net::ip::tcp::socket::shutdown_both, ignored);
    stream_.close();
    buffer_.clear();
    connect();
  }

  net::io_context ioc_;
  net::ip::tcp::endpoint endpoint_;
  beast::tcp_stream stream_{ioc_};
  beast::flat_buffer buffer_;
};

// wmd as a child process on a fresh database in its own directory, its output in wmd.log there; stopped with
// SIGTERM by stop() or the destructor. `binary`: another wmd build (a baseline), this build's by default.
class WmdProcess {
 public:
  explicit WmdProcess(const std::vector<std::string>& extra_args, std::string binary = WM_WMD) {
    const fs::path log = dir_.path() / "wmd.log";
    std::vector<std::string> args = {
        binary,  "--db", (dir_.path() / "bench.db").string(), "--port", "0", "--sync", "full", "--no-watch-rules",
        "--web", ""};
    args.insert(args.end(), extra_args.begin(), extra_args.end());
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    const std::string log_path = log.string();
    pid_ = ::fork();
    if (pid_ < 0) throw std::runtime_error("fork failed");
    if (pid_ == 0) {                       // only async-signal-safe calls until exec
      ::prctl(PR_SET_PDEATHSIG, SIGTERM);  // no wmd left behind by a crashed bench
      const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd >= 0) {
        ::dup2(fd, STDOUT_FILENO);
        ::dup2(fd, STDERR_FILENO);
      }
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
    // wmd prints "wmd: listening on http://127.0.0.1:PORT/" to stdout once it accepts connections; a file rather
    // than a pipe, so that nothing it writes later can block it.
    const auto deadline = Clock::now() + std::chrono::seconds(60);
    while (!(port_ = listening_port(log))) {
      if (int status = 0; ::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        throw std::runtime_error("wmd exited at start: " + head_of(log));
      }
      if (Clock::now() > deadline) throw std::runtime_error("wmd printed no port within 60 s: " + head_of(log));
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    wait_healthy(deadline);
  }
  ~WmdProcess() { stop(); }
  WmdProcess(const WmdProcess&) = delete;
  WmdProcess& operator=(const WmdProcess&) = delete;

  unsigned short port() const { return *port_; }
  /// Where its database is (bench.db, and the other maps in bench.db.maps/).
  const fs::path& dir() const { return dir_.path(); }

  /// CPU time wmd has used so far, user and system, all threads [s] (from /proc; 0 when unreadable). What ingest costs
  /// in CPU does not depend on what else the machine runs, unlike its rate.
  double cpu_seconds() const { return stat_cpu_seconds("/proc/" + std::to_string(pid_) + "/stat").second; }

  /// The same per thread name (the processing network's executors name their threads; the rest are "wmd"), summed
  /// over the threads that share a name.
  std::map<std::string, double> cpu_seconds_by_thread() const {
    std::map<std::string, double> out;
    std::error_code ec;
    for (const auto& task : fs::directory_iterator("/proc/" + std::to_string(pid_) + "/task", ec)) {
      // schedstat's first field is the thread's time on a CPU in ns: exact, where stat counts clock ticks.
      std::ifstream schedstat(task.path() / "schedstat");
      unsigned long long on_cpu_ns = 0;
      if (!(schedstat >> on_cpu_ns)) continue;
      out[stat_cpu_seconds(task.path() / "stat").first] += static_cast<double>(on_cpu_ns) * 1e-9;
    }
    return out;
  }

  /// SIGTERM, then waits; true when wmd exited 0. SIGKILL after 60 s so a hung shutdown cannot hang the bench.
  bool stop() {
    if (pid_ <= 0) return true;
    ::kill(pid_, SIGTERM);
    const auto deadline = Clock::now() + std::chrono::seconds(60);
    int status = 0;
    while (::waitpid(pid_, &status, WNOHANG) == 0) {
      if (Clock::now() > deadline) {
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, &status, 0);
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    pid_ = -1;
    return WIFEXITED(status) && WEXITSTATUS(status) == 0;
  }

 private:
  // A /proc stat file's name field and its utime + stime [s].
  static std::pair<std::string, double> stat_cpu_seconds(const fs::path& stat) {
    const std::string text = read_text(stat);
    const auto start_of_name = text.find('(');
    const auto end_of_name = text.rfind(')');  // the name may hold spaces and parentheses: fields count after it
    if (start_of_name == std::string::npos || end_of_name == std::string::npos || end_of_name < start_of_name)
      return {"", 0.0};
    std::istringstream fields(text.substr(end_of_name + 1));
    std::string field;
    unsigned long long utime = 0, stime = 0;
    for (int i = 3; i <= 15 && fields >> field; ++i) {  // field 3 is the state; 14 utime, 15 stime
      if (i == 14) utime = std::stoull(field);
      if (i == 15) stime = std::stoull(field);
    }
    return {text.substr(start_of_name + 1, end_of_name - start_of_name - 1),
            static_cast<double>(utime + stime) / static_cast<double>(::sysconf(_SC_CLK_TCK))};
  }

  // The start of wmd's output, enough for the reason it gives (a bad flag prints the whole usage).
  static std::string head_of(const fs::path& file) { return read_text(file).substr(0, 400); }

  static std::string read_text(const fs::path& file) {
    std::ifstream in(file);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }

  static std::optional<unsigned short> listening_port(const fs::path& log) {
    const std::string text = read_text(log);
    const std::string marker = "listening on http://";
    const auto at = text.find(marker);
    if (at == std::string::npos) return std::nullopt;
    const auto end = text.find('/', at + marker.size());
    const auto colon = text.rfind(':', end);
    if (end == std::string::npos || colon == std::string::npos || colon < at) return std::nullopt;
    return static_cast<unsigned short>(std::stoi(text.substr(colon + 1, end - colon - 1)));
  }

  void wait_healthy(Clock::time_point deadline) const {
    for (;;) {
      try {
        Connection c(port());
        if (c.request(http::verb::get, "/api/v1/health").status == 200) return;
      } catch (const boost::system::system_error&) {
      }
      if (Clock::now() > deadline) throw std::runtime_error("wmd's /api/v1/health did not answer 200 within 60 s");
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }

  TempDir dir_;
  pid_t pid_ = -1;
  std::optional<unsigned short> port_;
};

}  // namespace wm::bench
