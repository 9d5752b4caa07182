#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cstring>

#include "pipeline/network.h"

namespace wm::pipeline {
namespace {

[[noreturn]] void refuse(const std::string& source, const YAML::Node& at, const std::string& reason) {
  // Appended piece by piece: GCC 12 at -O3 reports a false -Wrestrict for `string += "literal" + string`.
  std::string message = source;
  if (at && at.Mark().line >= 0) {
    message += ':';
    message += std::to_string(at.Mark().line + 1);
  }
  message += ": ";
  message += reason;
  throw NetworkError(message);
}

std::string scalar(const std::string& source, const YAML::Node& node, const std::string& what) {
  if (!node || !node.IsScalar()) refuse(source, node, what + " must be a name");
  return node.as<std::string>();
}

std::vector<std::string> names(const std::string& source, const YAML::Node& node, const std::string& what) {
  if (!node.IsSequence()) refuse(source, node, what + " must be a list of names");
  std::vector<std::string> result;
  for (const auto& item : node) result.push_back(scalar(source, item, what));
  return result;
}

// "a.out -> b.in"
TaskSpec::Connection connection(const std::string& source, const YAML::Node& node) {
  const std::string text = scalar(source, node, "a connection");
  const auto arrow = text.find("->");
  const auto trim = [](std::string s) {
    const auto b = s.find_first_not_of(" \t"), e = s.find_last_not_of(" \t");
    return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
  };
  const auto split = [&](const std::string& end) -> std::pair<std::string, std::string> {
    const auto t = trim(end);
    const auto dot = t.find('.');
    if (dot == std::string::npos || dot == 0 || dot + 1 == t.size() || t.find('.', dot + 1) != std::string::npos)
      refuse(source, node, "connection '" + text + "': each end must be component.port");
    return {t.substr(0, dot), t.substr(dot + 1)};
  };
  if (arrow == std::string::npos) refuse(source, node, "connection '" + text + "' must read 'a.out -> b.in'");
  const auto [fc, fp] = split(text.substr(0, arrow));
  const auto [tc, tp] = split(text.substr(arrow + 2));
  return {fc, fp, tc, tp};
}

}  // namespace

TaskSpec parse_task(const std::string& yaml, const std::string& source) {
  YAML::Node root;
  try {
    root = YAML::Load(yaml);
  } catch (const YAML::Exception& e) {
    throw NetworkError(source + ":" + std::to_string(e.mark.line + 1) + ": not YAML: " + e.msg);
  }
  if (!root.IsMap()) throw NetworkError(source + ": a task file is a map with components, connections, executors");
  TaskSpec spec;
  spec.source = source;
  for (const auto& entry : root) {
    const auto key = entry.first.as<std::string>();
    if (key != "components" && key != "connections" && key != "executors" && key != "subtasks" && key != "description")
      refuse(source, entry.first,
             "unknown key '" + key + "' (components, connections, executors, subtasks, description)");
  }
  const auto components = root["components"];
  if (!components || !components.IsMap() || components.size() == 0)
    refuse(source, components, "'components' must map names to {kind: ...}");
  if (components.size() > kMaxComponents)
    refuse(source, components, "more than " + std::to_string(kMaxComponents) + " components");
  for (const auto& entry : components) {
    TaskSpec::ComponentSpec c;
    c.name = scalar(source, entry.first, "a component name");
    const auto& body = entry.second;
    if (!body.IsMap()) refuse(source, body, "component '" + c.name + "' must be a map with a kind");
    for (const auto& field : body) {
      const auto key = field.first.as<std::string>();
      if (key == "kind") {
        c.kind = scalar(source, field.second, "a kind");
      } else if (key == "functions") {
        c.functions = names(source, field.second, "functions");
      } else if (key == "priorities") {
        c.priorities = names(source, field.second, "priorities");
      } else if (key == "params") {
        if (!field.second.IsMap()) refuse(source, field.second, "params must be a map");
        std::map<std::string, std::string> values;
        for (const auto& p : field.second) values[p.first.as<std::string>()] = scalar(source, p.second, "a param");
        c.params = Params(std::move(values));
      } else if (key == "ports") {
        if (!field.second.IsMap()) refuse(source, field.second, "ports must map port names to {capacity, policy}");
        for (const auto& p : field.second) {
          const auto port = p.first.as<std::string>();
          if (!p.second.IsMap()) refuse(source, p.second, "port '" + port + "' must be {capacity: N, policy: P}");
          for (const auto& o : p.second) {
            const auto option = o.first.as<std::string>();
            const auto value = scalar(source, o.second, option);
            if (option == "capacity") {
              std::size_t used = 0;
              long long n = 0;
              try {
                n = std::stoll(value, &used);
              } catch (const std::exception&) {
                used = 0;
              }
              if (used != value.size() || n < 1 || n > 1000000)
                refuse(source, o.second, "capacity of '" + port + "' must be a whole number in [1, 1000000]");
              c.capacities[port] = static_cast<std::size_t>(n);
            } else if (option == "policy") {
              if (value == "fifo")
                c.policies[port] = PortPolicy::fifo;
              else if (value == "latest")
                c.policies[port] = PortPolicy::latest;
              else
                refuse(source, o.second, "policy of '" + port + "' must be fifo or latest");
            } else {
              refuse(source, o.first, "unknown port option '" + option + "' (capacity, policy)");
            }
          }
        }
      } else {
        refuse(source, field.first,
               "component '" + c.name + "': unknown key '" + key + "' (kind, params, functions, priorities, ports)");
      }
    }
    if (c.kind.empty()) refuse(source, body, "component '" + c.name + "' has no kind");
    spec.components.push_back(std::move(c));
  }
  if (const auto links = root["connections"]) {
    if (!links.IsSequence()) refuse(source, links, "'connections' must be a list of 'a.out -> b.in'");
    for (const auto& link : links) spec.connections.push_back(connection(source, link));
  }
  const auto executors = root["executors"];
  if (!executors || !executors.IsMap() || executors.size() == 0)
    refuse(source, executors, "'executors' must map thread names to lists of components");
  // Each executor is a thread.
  if (executors.size() > kMaxExecutors)
    refuse(source, executors, "more than " + std::to_string(kMaxExecutors) + " executors (each is a thread)");
  for (const auto& entry : executors) {
    TaskSpec::ExecutorSpec executor{scalar(source, entry.first, "an executor name"),
                                    names(source, entry.second, "an executor's components")};
    if (executor.components.empty()) refuse(source, entry.second, "executor '" + executor.name + "' runs no component");
    spec.executors.push_back(std::move(executor));
  }
  // subtasks: {name: {components: [...], running: true|false}}
  if (const auto subtasks = root["subtasks"]) {
    if (!subtasks.IsMap()) refuse(source, subtasks, "'subtasks' must map names to {components: [...], running: B}");
    for (const auto& entry : subtasks) {
      TaskSpec::SubtaskSpec subtask;
      subtask.name = scalar(source, entry.first, "a subtask name");
      const auto& body = entry.second;
      if (!body.IsMap()) refuse(source, body, "subtask '" + subtask.name + "' must be {components: [...], running: B}");
      bool named = false;
      for (const auto& field : body) {
        const auto key = field.first.as<std::string>();
        if (key == "components") {
          subtask.components = names(source, field.second, "a subtask's components");
          named = true;
        } else if (key == "running") {
          const auto value = scalar(source, field.second, "running");
          if (value != "true" && value != "false")
            refuse(source, field.second, "subtask '" + subtask.name + "': running must be true or false");
          subtask.running = value == "true";
        } else {
          refuse(source, field.first,
                 "subtask '" + subtask.name + "': unknown key '" + key + "' (components, running)");
        }
      }
      if (!named || subtask.components.empty())
        refuse(source, body, "subtask '" + subtask.name + "' names no component");
      spec.subtasks.push_back(std::move(subtask));
    }
  }
  return spec;
}

TaskSpec read_task_file(const std::string& path) {
  // Without O_NONBLOCK, opening a FIFO would wait for a writer; /dev/zero and the like never end: only a regular
  // file of bounded size is read.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw NetworkError(path + ": cannot be read (" + std::strerror(errno) + ")");
  struct stat info {};
  std::string text;
  std::string error;
  if (::fstat(fd, &info) != 0) {
    error = std::string("cannot be read (") + std::strerror(errno) + ")";
  } else if (!S_ISREG(info.st_mode)) {
    error = "not a regular file";
  } else if (static_cast<std::uint64_t>(info.st_size) > kMaxTaskFileBytes) {
    text.resize(kMaxTaskFileBytes + 1);  // reported below
  } else {
    // The size is read again as it comes: the file may grow after fstat.
    char buffer[64 * 1024];
    for (;;) {
      const auto got = ::read(fd, buffer, sizeof buffer);
      if (got < 0 && errno == EINTR) continue;
      if (got < 0) {
        error = std::string("cannot be read (") + std::strerror(errno) + ")";
        break;
      }
      if (got == 0) break;
      text.append(buffer, static_cast<std::size_t>(got));
      if (text.size() > kMaxTaskFileBytes) break;
    }
  }
  ::close(fd);
  if (error.empty() && text.size() > kMaxTaskFileBytes)
    error = "larger than " + std::to_string(kMaxTaskFileBytes >> 10) + " KiB: not a task file";
  if (!error.empty()) throw NetworkError(path + ": " + error);
  return parse_task(text, path);
}

}  // namespace wm::pipeline
