#pragma once

#include <stdexcept>
#include <string>

namespace wm::json_codec {

/// JSON the codec refuses to read or write. what() is the detail a client sees: "<field path>: <message>" (the
/// path like "segments[1].p0[0]", omitted when the whole text is at fault).
class CodecError : public std::runtime_error {
 public:
  enum class Kind {
    bad_request,       // a request body or text that is malformed, out of range or of the wrong shape
    answer_too_large,  // an answer that would exceed the size or nesting the server sends
  };
  CodecError(Kind kind, const std::string& path, const std::string& message)
      : std::runtime_error(path.empty() ? message : path + ": " + message),
        kind_(kind),
        path_(path),
        message_(message) {}
  Kind kind() const { return kind_; }
  /// The field path alone (empty: the whole text), and the message without it.
  const std::string& path() const { return path_; }
  const std::string& message() const { return message_; }

 private:
  Kind kind_;
  std::string path_;
  std::string message_;
};

/// The bad_request error for `path` (the field path, empty for the whole text).
inline CodecError bad_request(const std::string& path, const std::string& message) {
  return CodecError(CodecError::Kind::bad_request, path, message);
}

}  // namespace wm::json_codec
