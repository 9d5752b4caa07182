#include "clients/wmctl/cli.h"

#include <algorithm>
#include <fstream>
#include <iomanip>
#include <sstream>

namespace wm::wmctl {

std::optional<std::string> Invocation::flag(std::string_view name) const {
  std::optional<std::string> value;
  for (const auto& [flag, given] : flags)
    if (flag == name) value = given;
  return value;
}

std::string usage_line(const Command& command) {
  std::string line(command.name);
  for (const auto operand : command.operands) line += " " + std::string(operand);
  for (const auto& flag : command.flags) {
    const std::string text = std::string(flag.name) + (flag.value.empty() ? "" : " " + std::string(flag.value));
    line += flag.required ? " " + text : " [" + text + "]";
  }
  return line;
}

void parse_arguments(const Command& command, const std::vector<std::string>& words, Invocation& into) {
  const std::string name(command.name);
  if (words.size() < command.operands.size())
    throw UsageError(name + " needs " + std::string(command.operands[words.size()]));
  // Operands come first and are taken as they are, so a query goal may start with "--". A last operand named
  // "X..." takes every word up to the first flag.
  std::size_t end = command.operands.size();
  if (!command.operands.empty() && command.operands.back().ends_with("..."))
    while (end < words.size() && !words[end].starts_with("--")) ++end;
  into.operands.assign(words.begin(), words.begin() + static_cast<std::ptrdiff_t>(end));
  for (std::size_t i = end; i < words.size(); i += 2) {
    const auto known = std::find_if(command.flags.begin(), command.flags.end(),
                                    [&](const Flag& flag) { return flag.name == words[i]; });
    if (known == command.flags.end()) {
      if (command.flags.empty()) throw UsageError(name + " takes no '" + words[i] + "'");
      std::string accepted;
      for (const auto& flag : command.flags) accepted += (accepted.empty() ? "" : ", ") + std::string(flag.name);
      throw UsageError(name + ": unknown flag '" + words[i] + "'; it takes " + accepted);
    }
    if (known->value.empty()) {  // a switch: present or not
      into.flags.emplace_back(words[i], "true");
      --i;
      continue;
    }
    if (i + 1 >= words.size()) throw UsageError(words[i] + " needs " + std::string(known->value));
    into.flags.emplace_back(words[i], words[i + 1]);
  }
  for (const auto& flag : command.flags)
    if (flag.required && !into.flag(flag.name))
      throw UsageError(name + " needs " + std::string(flag.name) + " " + std::string(flag.value));
}

json parse_answer(const client::HttpResult& answer) {
  json body = json::parse(answer.body, nullptr, false);
  if (answer.status >= 400) {
    std::string message = "server answered " + std::to_string(answer.status);
    if (body.is_object() && body.contains("error"))
      message += " " + body.value("error", "") + ": " + body.value("detail", "");
    else
      message += ": " + answer.body.substr(0, 200);
    throw ServerError(message);
  }
  if (body.is_discarded()) throw ServerError("server answered something that is not JSON");
  return body;
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw UsageError("cannot read '" + path + "'");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

void write_file(const std::string& path, const std::string& data) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out || !(out << data)) throw UsageError("cannot write '" + path + "'");
}

std::int64_t parse_count(const std::string& text) {
  try {
    std::size_t used = 0;
    const auto n = std::stoll(text, &used);
    if (used == text.size() && n > 0) return n;
  } catch (const std::exception&) {
  }
  throw UsageError("expected a positive count, got '" + text + "'");
}

std::string fixed(double v, int digits) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(digits) << v;
  return s.str();
}

namespace {

std::string optional_text(const json& v) { return v.is_null() ? "-" : v.get<std::string>(); }

}  // namespace

void print_decision(const json& d) {
  std::cout << "#" << d["seq"].get<long long>() << "  " << std::left << std::setw(13) << d["action"].get<std::string>()
            << std::setw(24) << d["rule"].get<std::string>() << " element " << std::setw(12)
            << optional_text(d["element"]) << " object " << std::setw(12) << optional_text(d["object"])
            << (d["fallback"].get<bool>() ? " FALLBACK" : "") << "\n      " << d["explanation"].get<std::string>()
            << "\n";
}

}  // namespace wm::wmctl
