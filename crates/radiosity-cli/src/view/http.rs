//! The small part of HTTP/1.1 (RFC 9110, RFC 9112) the viewer speaks: request heads without
//! bodies, and responses with a known length or an open-ended event stream.
//!
//! Parsing is strict and bounded: a request head is at most [`MAX_HEAD`] bytes and
//! [`MAX_HEADERS`] header lines, ASCII only, no obsolete line folding; a request that carries
//! a body (`Content-Length` > 0 or any `Transfer-Encoding`) is refused, since no endpoint takes
//! one. The request target is kept exactly as sent (no percent-decoding, no normalisation):
//! routing compares it with a fixed table, so `..`, `%2e%2e`, `%2f` or double encodings can
//! only ever fail to match.

use std::io::{self, Write};

/// Largest accepted request head (request line and headers), bytes.
pub const MAX_HEAD: usize = 8 * 1024;
/// Largest accepted number of header lines.
pub const MAX_HEADERS: usize = 64;

/// A parsed request head.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Request {
    /// The method, e.g. `GET` (case-sensitive, RFC 9110 §9.1).
    pub method: String,
    /// The path part of the request target, exactly as sent.
    pub path: String,
    /// The query (after `?`), exactly as sent; empty if none.
    pub query: String,
    /// Minor version: 0 for HTTP/1.0, 1 for HTTP/1.1.
    pub minor: u8,
    /// Header lines in order, names lower-cased, values trimmed.
    pub headers: Vec<(String, String)>,
}

impl Request {
    /// The value of the only header named `name` (lower case); an error if it appears more
    /// than once.
    pub fn header(&self, name: &str) -> Result<Option<&str>, DuplicateHeader> {
        let mut found = None;
        for (n, v) in &self.headers {
            if n == name {
                if found.is_some() {
                    return Err(DuplicateHeader);
                }
                found = Some(v.as_str());
            }
        }
        Ok(found)
    }

    /// Whether the connection may serve another request after this one (RFC 9112 §9.3).
    pub fn keep_alive(&self) -> bool {
        let tokens = self
            .headers
            .iter()
            .filter(|(n, _)| n == "connection")
            .flat_map(|(_, v)| v.split(','))
            .map(|t| t.trim().to_ascii_lowercase())
            .collect::<Vec<_>>();
        if self.minor == 0 {
            tokens.iter().any(|t| t == "keep-alive")
        } else {
            !tokens.iter().any(|t| t == "close")
        }
    }
}

/// A header that may appear once appeared more than once (e.g. two `Host` lines).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DuplicateHeader;

/// Why a request head was refused; each maps to a status code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeadError {
    /// Malformed request line or header (400).
    BadRequest,
    /// The head exceeds [`MAX_HEAD`] bytes or [`MAX_HEADERS`] lines (431).
    TooLarge,
    /// A version other than HTTP/1.0 or HTTP/1.1 (505).
    Version,
    /// The request carries a body, which no endpoint takes (413 for a length, 400 for a
    /// transfer coding).
    Body,
}

impl HeadError {
    /// Status code and reason phrase of the error response.
    pub fn status(self) -> (u16, &'static str) {
        match self {
            Self::BadRequest => (400, "Bad Request"),
            Self::TooLarge => (431, "Request Header Fields Too Large"),
            Self::Version => (505, "HTTP Version Not Supported"),
            Self::Body => (413, "Content Too Large"),
        }
    }
}

/// Position just past the blank line that ends a request head in `buf`, if it is there.
pub fn head_end(buf: &[u8]) -> Option<usize> {
    buf.windows(4).position(|w| w == b"\r\n\r\n").map(|p| p + 4)
}

fn is_token(s: &str) -> bool {
    !s.is_empty()
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"!#$%&'*+-.^_`|~".contains(&b))
}

/// Parses a complete request head (up to and including the blank line).
pub fn parse_head(head: &[u8]) -> Result<Request, HeadError> {
    if head.len() > MAX_HEAD {
        return Err(HeadError::TooLarge);
    }
    let text = std::str::from_utf8(head).map_err(|_| HeadError::BadRequest)?;
    if !text.is_ascii() || text.bytes().any(|b| b == 0) {
        return Err(HeadError::BadRequest);
    }
    let mut lines = text
        .strip_suffix("\r\n\r\n")
        .ok_or(HeadError::BadRequest)?
        .split("\r\n");
    let request_line = lines.next().ok_or(HeadError::BadRequest)?;
    let mut parts = request_line.split(' ');
    let (Some(method), Some(target), Some(version), None) =
        (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Err(HeadError::BadRequest);
    };
    if !is_token(method) || target.is_empty() || target.bytes().any(|b| b <= b' ' || b == 0x7f) {
        return Err(HeadError::BadRequest);
    }
    let minor = match version {
        "HTTP/1.1" => 1,
        "HTTP/1.0" => 0,
        v if v.starts_with("HTTP/") => return Err(HeadError::Version),
        _ => return Err(HeadError::BadRequest),
    };
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    let mut headers = Vec::new();
    for line in lines {
        if headers.len() == MAX_HEADERS {
            return Err(HeadError::TooLarge);
        }
        // Obsolete line folding (a line starting with white space) is refused (RFC 9112 §5.2).
        let (name, value) = line.split_once(':').ok_or(HeadError::BadRequest)?;
        if !is_token(name) || value.bytes().any(|b| b < b' ' && b != b'\t') {
            return Err(HeadError::BadRequest);
        }
        headers.push((
            name.to_ascii_lowercase(),
            value.trim_matches([' ', '\t']).to_owned(),
        ));
    }
    let request = Request {
        method: method.to_owned(),
        path: path.to_owned(),
        query: query.to_owned(),
        minor,
        headers,
    };
    if request
        .headers
        .iter()
        .any(|(n, _)| n == "transfer-encoding")
    {
        return Err(HeadError::Body);
    }
    match request.header("content-length") {
        Err(DuplicateHeader) => return Err(HeadError::BadRequest),
        Ok(Some(v)) if v != "0" => {
            return Err(if v.bytes().all(|b| b.is_ascii_digit()) {
                HeadError::Body
            } else {
                HeadError::BadRequest
            })
        }
        _ => {}
    }
    Ok(request)
}

/// Whether a `Host` header value names this server: `127.0.0.1`, `localhost` or `[::1]`
/// with exactly the bound port (DNS-rebinding defence: a page of another site that resolves
/// its own name to 127.0.0.1 still sends its own name).
pub fn host_allowed(host: &str, port: u16) -> bool {
    let Some((name, p)) = host.rsplit_once(':') else {
        return false;
    };
    let name_ok = name == "127.0.0.1" || name.eq_ignore_ascii_case("localhost") || name == "[::1]";
    name_ok && p.parse::<u16>() == Ok(port) && !p.starts_with(['+', '0'])
}

/// A response about to be written.
pub struct Response<'a> {
    /// Status code.
    pub status: u16,
    /// Reason phrase.
    pub reason: &'static str,
    /// Extra headers (besides length, connection and the common security headers).
    pub headers: Vec<(&'static str, String)>,
    /// The body (not sent for HEAD, but its length is).
    pub body: &'a [u8],
}

impl<'a> Response<'a> {
    /// A response with the given status, content type and body.
    pub fn new(status: u16, reason: &'static str, content_type: &str, body: &'a [u8]) -> Self {
        Self {
            status,
            reason,
            headers: vec![("Content-Type", content_type.to_owned())],
            body,
        }
    }

    /// A short plain-text response, for errors.
    pub fn text(status: u16, reason: &'static str) -> Response<'static> {
        Response::new(
            status,
            reason,
            "text/plain; charset=utf-8",
            reason.as_bytes(),
        )
    }

    /// Adds a header.
    pub fn with(mut self, name: &'static str, value: &str) -> Self {
        self.headers.push((name, value.to_owned()));
        self
    }
}

/// Headers sent with every response: no MIME sniffing, no embedding by other sites, no
/// referrer, no caching of live data by default.
pub const COMMON_HEADERS: &str = "X-Content-Type-Options: nosniff\r\n\
    Cross-Origin-Resource-Policy: same-origin\r\n\
    Referrer-Policy: no-referrer\r\n";

/// Writes a response with `Content-Length`; the body is left out for HEAD.
pub fn write_response(
    out: &mut impl Write,
    response: &Response<'_>,
    head_only: bool,
    keep_alive: bool,
) -> io::Result<()> {
    let mut head = format!("HTTP/1.1 {} {}\r\n", response.status, response.reason);
    for (name, value) in &response.headers {
        head.push_str(&format!("{name}: {value}\r\n"));
    }
    if !response.headers.iter().any(|(n, _)| *n == "Cache-Control") {
        head.push_str("Cache-Control: no-store\r\n");
    }
    head.push_str(COMMON_HEADERS);
    head.push_str(&format!("Content-Length: {}\r\n", response.body.len()));
    head.push_str(if keep_alive {
        "Connection: keep-alive\r\n\r\n"
    } else {
        "Connection: close\r\n\r\n"
    });
    out.write_all(head.as_bytes())?;
    if !head_only {
        out.write_all(response.body)?;
    }
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Request, HeadError> {
        parse_head(text.as_bytes())
    }

    #[test]
    fn parses_a_browser_request() {
        let r = parse(
            "GET /api/mesh?format=json HTTP/1.1\r\nHost: 127.0.0.1:8080\r\n\
             Accept: */*\r\nConnection: keep-alive\r\n\r\n",
        )
        .unwrap();
        assert_eq!(r.method, "GET");
        assert_eq!(r.path, "/api/mesh");
        assert_eq!(r.query, "format=json");
        assert_eq!(r.minor, 1);
        assert_eq!(r.header("host"), Ok(Some("127.0.0.1:8080")));
        assert!(r.keep_alive());
    }

    #[test]
    fn keeps_the_target_undecoded() {
        let r = parse("GET /assets/%2e%2e%2fCargo.toml HTTP/1.1\r\n\r\n").unwrap();
        assert_eq!(r.path, "/assets/%2e%2e%2fCargo.toml");
    }

    #[test]
    fn connection_persistence_follows_the_version() {
        assert!(!parse("GET / HTTP/1.0\r\n\r\n").unwrap().keep_alive());
        assert!(parse("GET / HTTP/1.0\r\nConnection: Keep-Alive\r\n\r\n")
            .unwrap()
            .keep_alive());
        assert!(!parse("GET / HTTP/1.1\r\nConnection: close\r\n\r\n")
            .unwrap()
            .keep_alive());
    }

    #[test]
    fn refuses_malformed_heads() {
        use HeadError::*;
        for (text, want) in [
            ("GET /\r\n\r\n", BadRequest),
            ("GET  / HTTP/1.1\r\n\r\n", BadRequest),
            ("GET / HTTP/1.1 x\r\n\r\n", BadRequest),
            ("GET / HTTP/2.0\r\n\r\n", Version),
            ("GET / FTP/1.0\r\n\r\n", BadRequest),
            ("G(T / HTTP/1.1\r\n\r\n", BadRequest),
            ("GET / HTTP/1.1\r\nHost 127.0.0.1\r\n\r\n", BadRequest),
            ("GET / HTTP/1.1\r\n folded: x\r\n\r\n", BadRequest),
            ("GET / HTTP/1.1\r\nX: a\u{1}b\r\n\r\n", BadRequest),
            ("GET /caf\u{e9} HTTP/1.1\r\n\r\n", BadRequest),
            ("GET / HTTP/1.1\r\nContent-Length: 5\r\n\r\n", Body),
            ("GET / HTTP/1.1\r\nContent-Length: -1\r\n\r\n", BadRequest),
            (
                "GET / HTTP/1.1\r\nContent-Length: 0\r\nContent-Length: 0\r\n\r\n",
                BadRequest,
            ),
            ("GET / HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n", Body),
        ] {
            assert_eq!(parse(text), Err(want), "{text:?}");
        }
        assert!(parse("GET / HTTP/1.1\r\nContent-Length: 0\r\n\r\n").is_ok());
    }

    #[test]
    fn bounds_the_head() {
        let many: String = (0..=MAX_HEADERS).map(|i| format!("X-{i}: y\r\n")).collect();
        assert_eq!(
            parse(&format!("GET / HTTP/1.1\r\n{many}\r\n")),
            Err(HeadError::TooLarge)
        );
        let long = "a".repeat(MAX_HEAD);
        assert_eq!(
            parse(&format!("GET /{long} HTTP/1.1\r\n\r\n")),
            Err(HeadError::TooLarge)
        );
    }

    #[test]
    fn host_must_name_this_server() {
        for ok in [
            "127.0.0.1:8080",
            "localhost:8080",
            "LocalHost:8080",
            "[::1]:8080",
        ] {
            assert!(host_allowed(ok, 8080), "{ok}");
        }
        for bad in [
            "127.0.0.1",
            "localhost",
            "127.0.0.1:8081",
            "127.0.0.1:08080",
            "127.0.0.1:+8080",
            "evil.example:8080",
            "localhost.evil.example:8080",
            "127.0.0.1.evil.example:8080",
            "127.0.0.2:8080",
            "0.0.0.0:8080",
            "[::]:8080",
            "",
            ":8080",
        ] {
            assert!(!host_allowed(bad, 8080), "{bad}");
        }
    }

    #[test]
    fn head_responses_keep_the_length_but_drop_the_body() {
        let r = Response::new(200, "OK", "text/plain", b"hello");
        let mut get = Vec::new();
        write_response(&mut get, &r, false, true).unwrap();
        let mut head = Vec::new();
        write_response(&mut head, &r, true, true).unwrap();
        let get = String::from_utf8(get).unwrap();
        let head = String::from_utf8(head).unwrap();
        assert!(get.ends_with("\r\n\r\nhello"));
        assert!(head.ends_with("\r\n\r\n"));
        assert!(head.contains("Content-Length: 5\r\n"));
        assert_eq!(get.strip_suffix("hello"), Some(head.as_str()));
    }
}
