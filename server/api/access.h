#pragma once

// Who may ask: the Host check (DNS rebinding), the Origin allow-list (cross-site requests from browsers) and the
// bearer token. Each refusal is an ApiError with its status.
#include <optional>

#include "server/api/api_options.h"
#include "server/api/http_types.h"

namespace wm::api {

/// Against DNS rebinding: a page of attacker.example that re-resolves its name to 127.0.0.1 reaches us with
/// "Host: attacker.example". IP literals cannot be rebound, so they always pass; a request without Host
/// (HTTP/1.0, no browser) too. @throw ApiError(421, "misdirected_request").
void require_allowed_host(const Request& request, const ApiOptions& options);

/// Same origin (the Origin's host:port is the Host header) or one of options.allowed_origins. A request without
/// Origin does not come from a browser page and passes; one with more than one Origin header is refused.
/// @throw ApiError(403, "forbidden_origin").
void require_allowed_origin(const Request& request, const ApiOptions& options);

/// When a token is configured: "Authorization: Bearer <token>". @throw ApiError(401, "unauthorized").
void require_token(const Request& request, const ApiOptions& options);

/// Whether the request's Sec-WebSocket-Protocol headers (comma-separated lists, RFC 6455 section 4.1) name
/// `protocol` (compared exactly: subprotocol names are case-sensitive).
bool offers_subprotocol(const Request& request, std::string_view protocol);

/// Decides a WebSocket upgrade: the Host check, the Origin allow-list (same origin by default) and, when a token
/// is configured, "Authorization: Bearer <token>" or "?token=<token>" (browsers cannot set headers on a
/// WebSocket). nullopt: upgrade; otherwise the refusal to send (421, 403 or 401). Never throws.
std::optional<Response> authorize_upgrade(const Request& request, const ApiOptions& options);

}  // namespace wm::api
