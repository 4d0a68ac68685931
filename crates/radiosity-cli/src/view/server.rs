//! The viewer's HTTP/1.1 server: loopback only, GET and HEAD of a fixed set of paths.
//!
//! | path | what |
//! | --- | --- |
//! | `/` | the page (`index.html`) |
//! | `/assets/<name>` | an embedded asset, by exact name ([`super::assets::ASSETS`]) |
//! | `/api/mesh` | the current [`ViewMesh`](super::ViewMesh), binary (`?format=json`: JSON) |
//! | `/api/frame` | the latest [`ViewFrame`](super::ViewFrame), binary (`?format=json`: JSON) |
//! | `/api/progress` | the current [`StateNotice`] as JSON |
//! | `/events` | server-sent events (WHATWG HTML §9.2): a `state` event with the notice whenever it changes, at most one per [`ServerConfig::event_interval`] |
//!
//! Anything else is 404; other methods on these paths are 405. A request whose `Host` is not
//! `127.0.0.1:PORT`, `localhost:PORT` or `[::1]:PORT` is refused with 403 (DNS rebinding).
//!
//! One thread per connection, at most [`ServerConfig::max_connections`] at once (the next
//! gets 503) and at most [`ServerConfig::max_event_streams`] of them event streams; every
//! read and write has a timeout, and a request head must arrive whole within
//! [`ServerConfig::io_timeout`]. Shutting down ([`ShutdownHandle::shutdown`]) closes the
//! listener and every open connection, event streams included, so the server stops within a
//! fraction of a second whatever its clients do.

use super::assets::{self, Asset};
use super::http::{self, HeadError, Request, Response, MAX_HEAD};
use super::protocol::{ViewError, ViewState};
use std::collections::HashMap;
use std::io::{ErrorKind, Read, Write};
use std::net::{Ipv4Addr, Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

/// Limits and timing of the server.
#[derive(Debug, Clone)]
pub struct ServerConfig {
    /// Port on 127.0.0.1; 0 picks any free port.
    pub port: u16,
    /// Most connections served at once (each holds a thread).
    pub max_connections: usize,
    /// Most event streams at once (a subset of the connections).
    pub max_event_streams: usize,
    /// Longest wait for a request head, and for each read or write on a socket.
    pub io_timeout: Duration,
    /// Longest a kept-alive connection may sit idle between requests.
    pub idle_timeout: Duration,
    /// Shortest time between two notices on one event stream: bursts of changes in between
    /// are coalesced into the latest state.
    pub event_interval: Duration,
    /// An event stream with nothing to say sends a comment this often, so that a closed
    /// browser tab is noticed.
    pub heartbeat: Duration,
}

impl Default for ServerConfig {
    fn default() -> Self {
        Self {
            port: 0,
            max_connections: 32,
            max_event_streams: 8,
            io_timeout: Duration::from_secs(10),
            idle_timeout: Duration::from_secs(30),
            event_interval: Duration::from_millis(250),
            heartbeat: Duration::from_secs(15),
        }
    }
}

/// How often blocked threads look at the stop flag; bounds the shutdown latency of a
/// thread that is waiting on a socket.
const POLL: Duration = Duration::from_millis(50);

/// How often the accept loop looks for a new connection (and at the stop flag): the most a
/// new connection waits before it is accepted.
const ACCEPT_POLL: Duration = Duration::from_millis(20);

/// Most requests served on one connection before it is closed.
const MAX_REQUESTS_PER_CONNECTION: usize = 1000;

/// Stops a running server from any thread (the solver, a Ctrl-C handler).
#[derive(Clone)]
pub struct ShutdownHandle {
    stop: Arc<AtomicBool>,
    state: Arc<ViewState>,
}

impl ShutdownHandle {
    /// Asks the server to stop: it closes its port and every connection and returns from
    /// [`Server::run`]. Returns at once; idempotent.
    pub fn shutdown(&self) {
        self.stop.store(true, Ordering::SeqCst);
        self.state.wake_all();
    }

    /// Whether [`ShutdownHandle::shutdown`] was called (a solver loop may poll this to stop
    /// early on Ctrl-C).
    pub fn is_shutdown(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }
}

/// Live connections, so that shutdown can close them.
#[derive(Default)]
struct Connections {
    open: Mutex<HashMap<u64, (TcpStream, bool)>>,
    next_id: AtomicU64,
}

impl Connections {
    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<u64, (TcpStream, bool)>> {
        self.open.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn close_all(&self) {
        for (stream, _) in self.lock().values() {
            let _ = stream.shutdown(Shutdown::Both);
        }
    }
}

/// Removes a connection from the table when its thread ends, however it ends.
struct Registration<'a> {
    connections: &'a Connections,
    id: u64,
}

impl Drop for Registration<'_> {
    fn drop(&mut self) {
        self.connections.lock().remove(&self.id);
    }
}

/// The viewer's server, bound and ready to run.
pub struct Server {
    listener: TcpListener,
    addr: SocketAddr,
    shared: Arc<Context>,
}

/// What every connection thread needs.
struct Context {
    state: Arc<ViewState>,
    config: ServerConfig,
    stop: Arc<AtomicBool>,
    connections: Connections,
    port: u16,
}

impl Context {
    fn stopping(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }
}

/// A server running on its own thread (from [`Server::spawn`]).
// The command only joins it; the tests use the rest.
#[cfg_attr(not(test), allow(dead_code))]
pub struct RunningServer {
    thread: JoinHandle<Result<(), ViewError>>,
    handle: ShutdownHandle,
    addr: SocketAddr,
}

#[cfg_attr(not(test), allow(dead_code))]
impl RunningServer {
    /// The handle that stops it.
    pub fn shutdown_handle(&self) -> ShutdownHandle {
        self.handle.clone()
    }

    /// The bound address (always 127.0.0.1).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// The page's address, `http://127.0.0.1:PORT/`.
    pub fn url(&self) -> String {
        url_of(self.addr)
    }

    /// Stops the server and waits for it.
    pub fn stop(self) -> Result<(), ViewError> {
        self.handle.shutdown();
        self.join()
    }

    /// Waits until the server stops (after a shutdown from elsewhere, e.g. Ctrl-C).
    pub fn join(self) -> Result<(), ViewError> {
        self.thread.join().unwrap_or_else(|_| {
            Err(ViewError::Io {
                context: "the server thread panicked",
                source: std::io::Error::other("panic"),
            })
        })
    }
}

fn url_of(addr: SocketAddr) -> String {
    format!("http://{addr}/")
}

impl Server {
    /// Binds 127.0.0.1:`config.port` (never another interface).
    pub fn bind(state: Arc<ViewState>, config: ServerConfig) -> Result<Self, ViewError> {
        let bind_err = |source| ViewError::Bind {
            port: config.port,
            source,
        };
        let listener = TcpListener::bind((Ipv4Addr::LOCALHOST, config.port)).map_err(bind_err)?;
        let addr = listener.local_addr().map_err(bind_err)?;
        // Accepting polls so that shutdown needs no wake-up connection.
        listener.set_nonblocking(true).map_err(bind_err)?;
        let shared = Arc::new(Context {
            state,
            port: addr.port(),
            config,
            stop: Arc::new(AtomicBool::new(false)),
            connections: Connections::default(),
        });
        Ok(Self {
            listener,
            addr,
            shared,
        })
    }

    /// The page's address, `http://127.0.0.1:PORT/`.
    pub fn url(&self) -> String {
        url_of(self.addr)
    }

    /// The handle that stops this server.
    pub fn shutdown_handle(&self) -> ShutdownHandle {
        ShutdownHandle {
            stop: self.shared.stop.clone(),
            state: self.shared.state.clone(),
        }
    }

    /// Runs the server on a thread of its own.
    pub fn spawn(self) -> Result<RunningServer, ViewError> {
        let handle = self.shutdown_handle();
        let addr = self.addr;
        let thread = thread::Builder::new()
            .name("view-server".to_owned())
            .spawn(move || self.run())
            .map_err(|source| ViewError::Io {
                context: "starting the server thread",
                source,
            })?;
        Ok(RunningServer {
            thread,
            handle,
            addr,
        })
    }

    /// Serves until shut down, then closes every connection and waits (at most a second)
    /// for their threads.
    pub fn run(self) -> Result<(), ViewError> {
        let ctx = &self.shared;
        let mut threads: Vec<JoinHandle<()>> = Vec::new();
        while !ctx.stopping() {
            threads.retain(|t| !t.is_finished());
            match self.listener.accept() {
                Ok((stream, peer)) => {
                    if let Some(t) = self.admit(stream, peer) {
                        threads.push(t);
                    }
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => thread::sleep(ACCEPT_POLL),
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                // Out of descriptors or a connection reset before accept: wait and go on.
                Err(_) => thread::sleep(POLL),
            }
        }
        drop(self.listener);
        ctx.connections.close_all();
        ctx.state.wake_all();
        let deadline = Instant::now() + Duration::from_secs(1);
        while threads.iter().any(|t| !t.is_finished()) && Instant::now() < deadline {
            thread::sleep(Duration::from_millis(5));
        }
        for t in threads {
            if t.is_finished() {
                let _ = t.join();
            }
        }
        Ok(())
    }

    /// Registers a new connection and starts its thread, or refuses it with 503.
    fn admit(&self, stream: TcpStream, peer: SocketAddr) -> Option<JoinHandle<()>> {
        let ctx = &self.shared;
        // Bound to 127.0.0.1, so every peer is local; refuse anything else all the same.
        if !peer.ip().is_loopback() {
            return None;
        }
        // Accepted sockets inherit non-blocking mode on some systems.
        stream.set_nonblocking(false).ok()?;
        stream.set_write_timeout(Some(ctx.config.io_timeout)).ok()?;
        stream.set_nodelay(true).ok()?;
        let id = ctx.connections.next_id.fetch_add(1, Ordering::Relaxed);
        {
            let mut open = ctx.connections.lock();
            if open.len() >= ctx.config.max_connections {
                drop(open);
                refuse_busy(stream);
                return None;
            }
            open.insert(id, (stream.try_clone().ok()?, false));
        }
        let ctx = self.shared.clone();
        let spawned = thread::Builder::new()
            .name("view-connection".to_owned())
            .spawn(move || {
                let _registration = Registration {
                    connections: &ctx.connections,
                    id,
                };
                serve_connection(&ctx, stream, id);
            });
        match spawned {
            Ok(t) => Some(t),
            Err(_) => {
                // The closure (and its registration) is gone; drop the table entry.
                if let Some((s, _)) = self.shared.connections.lock().remove(&id) {
                    let _ = s.shutdown(Shutdown::Both);
                }
                None
            }
        }
    }
}

fn refuse_busy(mut stream: TcpStream) {
    let _ = stream.set_write_timeout(Some(Duration::from_secs(1)));
    let r = Response::text(503, "Service Unavailable").with("Retry-After", "1");
    let _ = http::write_response(&mut stream, &r, false, false);
    let _ = stream.shutdown(Shutdown::Both);
}

/// What reading the next request head came to.
enum Next {
    Head(Vec<u8>),
    /// The client closed, went idle too long, or the server is stopping: close quietly.
    Close,
    /// A head arrived but is unacceptable: answer with this status and close.
    Refuse(HeadError),
    /// The client took too long to send a head it had started: 408 and close.
    TooSlow,
}

/// Reads until a whole request head is in `buf`, honouring the size limit, the deadlines
/// and the stop flag. Bytes after the head stay in `buf` (a pipelined next request).
fn read_head(ctx: &Context, stream: &mut TcpStream, buf: &mut Vec<u8>) -> Next {
    let started = Instant::now();
    let mut chunk = [0u8; 2048];
    loop {
        if let Some(end) = http::head_end(buf) {
            if end > MAX_HEAD {
                return Next::Refuse(HeadError::TooLarge);
            }
            let rest = buf.split_off(end);
            return Next::Head(std::mem::replace(buf, rest));
        }
        if buf.len() > MAX_HEAD {
            return Next::Refuse(HeadError::TooLarge);
        }
        if ctx.stopping() {
            return Next::Close;
        }
        let limit = if buf.is_empty() {
            ctx.config.idle_timeout
        } else {
            ctx.config.io_timeout
        };
        let elapsed = started.elapsed();
        if elapsed >= limit {
            return if buf.is_empty() {
                Next::Close
            } else {
                Next::TooSlow
            };
        }
        // Short reads, so that the stop flag and the deadline are looked at often.
        let wait = (limit - elapsed)
            .min(POLL * 4)
            .max(Duration::from_millis(1));
        if stream.set_read_timeout(Some(wait)).is_err() {
            return Next::Close;
        }
        match stream.read(&mut chunk) {
            Ok(0) => return Next::Close,
            Ok(n) => buf.extend_from_slice(&chunk[..n]),
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                ) => {}
            Err(_) => return Next::Close,
        }
    }
}

/// Answers with an error and closes. The client may have sent more than was read (a body,
/// the rest of an oversized head); closing with unread input makes the system reset the
/// connection, which can destroy the response before the client reads it, so the input is
/// drained (briefly, and a bounded amount) after the response is sent (RFC 9112 §9.6).
fn refuse(mut stream: TcpStream, response: Response<'_>, head_only: bool) {
    if http::write_response(&mut stream, &response, head_only, false).is_err() {
        return;
    }
    let _ = stream.shutdown(Shutdown::Write);
    let deadline = Instant::now() + Duration::from_millis(500);
    let mut sink = [0u8; 4096];
    let mut drained = 0usize;
    while Instant::now() < deadline && drained < 1 << 20 {
        let _ = stream.set_read_timeout(Some(Duration::from_millis(50)));
        match stream.read(&mut sink) {
            Ok(0) => return,
            Ok(n) => drained += n,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {}
            Err(_) => return,
        }
    }
}

/// Serves requests on one connection until it closes.
fn serve_connection(ctx: &Context, mut stream: TcpStream, id: u64) {
    let mut buf = Vec::new();
    for _ in 0..MAX_REQUESTS_PER_CONNECTION {
        let head = match read_head(ctx, &mut stream, &mut buf) {
            Next::Head(head) => head,
            Next::Close => return,
            Next::TooSlow => {
                refuse(stream, Response::text(408, "Request Timeout"), false);
                return;
            }
            Next::Refuse(e) => {
                let (code, reason) = e.status();
                refuse(stream, Response::text(code, reason), false);
                return;
            }
        };
        let request = match http::parse_head(&head) {
            Ok(r) => r,
            Err(e) => {
                let (code, reason) = e.status();
                refuse(stream, Response::text(code, reason), false);
                return;
            }
        };
        let keep_alive = request.keep_alive() && !ctx.stopping();
        match respond(ctx, &request) {
            Reply::Events => {
                serve_events(ctx, stream, id, request.method == "HEAD");
                return;
            }
            Reply::Body(response) => {
                let head_only = request.method == "HEAD";
                if response.status >= 400 {
                    // Errors close the connection: a client that is refused has no reason
                    // to keep it, and a hostile one gets no second try on it.
                    refuse(stream, response.borrow(), head_only);
                    return;
                }
                if http::write_response(&mut stream, &response.borrow(), head_only, keep_alive)
                    .is_err()
                    || !keep_alive
                {
                    return;
                }
            }
        }
    }
}

/// A response body that may be shared with other connections.
enum Body {
    Static(&'static [u8]),
    Shared(Arc<Vec<u8>>),
    Owned(Vec<u8>),
}

/// A response whose body outlives the state lock.
struct Owned {
    status: u16,
    reason: &'static str,
    headers: Vec<(&'static str, String)>,
    body: Body,
}

impl Owned {
    fn borrow(&self) -> Response<'_> {
        Response {
            status: self.status,
            reason: self.reason,
            headers: self.headers.clone(),
            body: match &self.body {
                Body::Static(b) => b,
                Body::Shared(b) => b.as_slice(),
                Body::Owned(b) => b.as_slice(),
            },
        }
    }

    fn error(status: u16, reason: &'static str) -> Self {
        Self {
            status,
            reason,
            headers: vec![("Content-Type", "text/plain; charset=utf-8".to_owned())],
            body: Body::Static(reason.as_bytes()),
        }
    }

    fn ok(content_type: &str, body: Body) -> Self {
        Self {
            status: 200,
            reason: "OK",
            headers: vec![("Content-Type", content_type.to_owned())],
            body,
        }
    }
}

enum Reply {
    Body(Owned),
    Events,
}

/// The fixed route table: the exact path, nothing decoded or normalised.
enum Route {
    Page,
    Asset(&'static Asset),
    Mesh,
    Frame,
    Progress,
    Events,
}

fn route(path: &str) -> Option<Route> {
    match path {
        "/" => Some(Route::Page),
        "/api/mesh" => Some(Route::Mesh),
        "/api/frame" => Some(Route::Frame),
        "/api/progress" => Some(Route::Progress),
        "/events" => Some(Route::Events),
        _ => assets::asset(path.strip_prefix("/assets/")?).map(Route::Asset),
    }
}

fn wants_json(query: &str) -> bool {
    query.split('&').any(|p| p == "format=json")
}

fn json_body<T: serde::Serialize>(value: &T) -> Owned {
    match serde_json::to_vec(value) {
        Ok(bytes) => Owned::ok("application/json", Body::Owned(bytes)),
        Err(_) => Owned::error(500, "Internal Server Error"),
    }
}

fn respond(ctx: &Context, request: &Request) -> Reply {
    match request.header("host") {
        Err(http::DuplicateHeader) | Ok(None) => {
            return Reply::Body(Owned::error(400, "Bad Request"))
        }
        Ok(Some(host)) if !http::host_allowed(host, ctx.port) => {
            return Reply::Body(Owned::error(403, "Forbidden"))
        }
        Ok(Some(_)) => {}
    }
    let Some(route) = route(&request.path) else {
        return Reply::Body(Owned::error(404, "Not Found"));
    };
    if request.method != "GET" && request.method != "HEAD" {
        let mut r = Owned::error(405, "Method Not Allowed");
        r.headers.push(("Allow", "GET, HEAD".to_owned()));
        return Reply::Body(r);
    }
    let state = &ctx.state;
    let reply = match route {
        Route::Page => {
            let mut r = Owned::ok(
                assets::INDEX.content_type,
                Body::Static(assets::INDEX.bytes),
            );
            r.headers
                .push(("Content-Security-Policy", assets::content_security_policy()));
            r.headers.push(("X-Frame-Options", "DENY".to_owned()));
            r.headers.push(("Cache-Control", "no-cache".to_owned()));
            r
        }
        Route::Asset(a) => {
            let mut r = Owned::ok(a.content_type, Body::Static(a.bytes));
            r.headers.push(("Cache-Control", "no-cache".to_owned()));
            r
        }
        Route::Mesh if wants_json(&request.query) => match state.mesh() {
            Some(mesh) => json_body(&*mesh),
            None => Owned::error(404, "Not Found"),
        },
        Route::Mesh => match state.mesh_body() {
            Some(body) => Owned::ok("application/octet-stream", Body::Shared(body)),
            None => Owned::error(404, "Not Found"),
        },
        Route::Frame if wants_json(&request.query) => match state.frame() {
            Some(frame) => json_body(&*frame),
            None => Owned::error(404, "Not Found"),
        },
        Route::Frame => match state.frame_body() {
            Some(body) => Owned::ok("application/octet-stream", Body::Shared(body)),
            None => Owned::error(404, "Not Found"),
        },
        Route::Progress => json_body(&state.notice()),
        Route::Events => return Reply::Events,
    };
    Reply::Body(reply)
}

/// Serves `/events` until the client goes away or the server stops.
fn serve_events(ctx: &Context, mut stream: TcpStream, id: u64, head_only: bool) {
    {
        let mut open = ctx.connections.lock();
        let streams = open.values().filter(|(_, events)| *events).count();
        if streams >= ctx.config.max_event_streams {
            drop(open);
            let r = Response::text(503, "Service Unavailable").with("Retry-After", "5");
            let _ = http::write_response(&mut stream, &r, head_only, false);
            return;
        }
        if let Some(entry) = open.get_mut(&id) {
            entry.1 = true;
        }
    }
    let head = format!(
        "HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\nCache-Control: no-store\r\n{}\
         Connection: close\r\n\r\n",
        http::COMMON_HEADERS
    );
    if stream.write_all(head.as_bytes()).is_err() || head_only {
        return;
    }
    ctx.state.viewer_connected();
    // Browsers reconnect after this many milliseconds if the stream breaks.
    if stream.write_all(b"retry: 1000\n\n").is_err() {
        return;
    }
    let stop = || ctx.stopping();
    let mut seen = None;
    while !ctx.stopping() {
        let revision = ctx
            .state
            .wait_change(seen, Instant::now() + ctx.config.heartbeat, &stop);
        if ctx.stopping() {
            return;
        }
        let message = if Some(revision) == seen {
            ": heartbeat\n\n".to_owned()
        } else {
            let notice = ctx.state.notice();
            seen = Some(notice.revision);
            match serde_json::to_string(&notice) {
                Ok(json) => format!("event: state\ndata: {json}\n\n"),
                Err(_) => return,
            }
        };
        if stream
            .write_all(message.as_bytes())
            .and_then(|()| stream.flush())
            .is_err()
        {
            return;
        }
        // Coalesce: whatever changes in the next interval goes out as one notice.
        ctx.state
            .wait_stop(Instant::now() + ctx.config.event_interval, &stop);
    }
}
