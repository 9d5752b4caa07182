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
      : std::runtime_error(path.empty() ? message : path + ": " + message), kind_(kind) {}
  Kind kind() const { return kind_; }

 private:
  Kind kind_;
};

/// The bad_request error for `path` (the field path, empty for the whole text).
inline CodecError bad_request(const std::string& path, const std::string& message) {
  return CodecError(CodecError::Kind::bad_request, path, message);
}

}  // namespace wm::json_codec
