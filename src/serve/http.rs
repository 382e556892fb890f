//! The routes: the embedded page and three.js files, the live WebSocket,
//! the status, the picker's vertex query and the three controls. A guard in
//! front of every route rejects requests for another host (DNS rebinding)
//! or from another site's page (cross-site requests), and every response
//! forbids framing (clickjacking of the stop button).

use std::net::{IpAddr, SocketAddr};
use std::sync::Arc;
use std::time::Duration;

use axum::body::Bytes;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Path, Request, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, Uri, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use tokio::time::Instant;

use super::assets::{self, Page};
use super::state::{SNAPSHOT_INTERVAL, Shared};
use super::wire::{self, Rgbe};

/// Largest message a client may send; the page sends none, so anything
/// bigger is abuse.
const MAX_CLIENT_MESSAGE: usize = 4096;

#[derive(Clone)]
struct App {
    shared: Arc<Shared>,
}

/// The content security policy of the live view's page.
const LIVE_POLICY: &str = "default-src 'self'; script-src 'self' 'unsafe-inline'; \
     style-src 'self' 'unsafe-inline'; img-src 'self' data:; connect-src 'self'; \
     frame-ancestors 'none'; base-uri 'none'; form-action 'none'";

/// What guards a server's routes: the address it listens on and its
/// page's content security policy.
#[derive(Clone, Copy)]
pub struct Guard {
    /// The address the server listens on.
    pub local: SocketAddr,
    /// The `Content-Security-Policy` of every response.
    pub policy: &'static str,
}

impl Guard {
    /// `router` behind this guard ([`guard`]).
    pub fn around<S: Clone + Send + Sync + 'static>(self, router: Router<S>) -> Router<S> {
        router.layer(middleware::from_fn_with_state(self, guard))
    }
}

/// The router for a server listening on `local`.
pub fn router(shared: Arc<Shared>, local: SocketAddr) -> Router {
    let app = App { shared };
    let guard = Guard {
        local,
        policy: LIVE_POLICY,
    };
    let routes = Router::new()
        .route("/api/live", get(live))
        .route("/api/status", get(status))
        .route("/api/vertex/{index}", get(vertex))
        .route("/api/pause", post(pause))
        .route("/api/resume", post(resume))
        .route("/api/stop", post(stop))
        .route("/api/view/{width}/{height}", post(view))
        .route("/api/frame.png", get(frame))
        .fallback(get(|uri: Uri| async move { asset(Page::Live, &uri) }));
    guard.around(routes).with_state(app)
}

/// Rejects unexpected hosts and origins; adds the security headers.
async fn guard(State(guard): State<Guard>, request: Request, next: Next) -> Response {
    let headers = request.headers();
    if let Err(reason) = check_host(headers, guard.local) {
        return (StatusCode::FORBIDDEN, reason).into_response();
    }
    if let Err(reason) = check_origin(headers) {
        return (StatusCode::FORBIDDEN, reason).into_response();
    }
    let mut response = next.run(request).await;
    let h = response.headers_mut();
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        HeaderValue::from_static(guard.policy),
    );
    h.insert(header::X_FRAME_OPTIONS, HeaderValue::from_static("DENY"));
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        HeaderValue::from_static("nosniff"),
    );
    h.insert(
        header::REFERRER_POLICY,
        HeaderValue::from_static("no-referrer"),
    );
    h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    response
}

/// The `Host` header must name this server: `localhost` or an address it
/// listens on, with its port. A page on another site whose name was made
/// to resolve to 127.0.0.1 (DNS rebinding) carries its own name and is
/// refused. A request without `Host` (HTTP/1.0, not a browser) passes.
pub fn check_host(headers: &HeaderMap, local: SocketAddr) -> Result<(), String> {
    let Some(value) = headers.get(header::HOST) else {
        return Ok(());
    };
    let refuse = || {
        Err(format!(
            "unexpected Host header; open the page at http://{local}/"
        ))
    };
    let Ok(authority) = value
        .to_str()
        .map_err(|_| ())
        .and_then(|v| v.parse::<axum::http::uri::Authority>().map_err(|_| ()))
    else {
        return refuse();
    };
    if authority.port_u16().unwrap_or(80) != local.port() {
        return refuse();
    }
    let host = authority.host();
    let host = host.strip_suffix('.').unwrap_or(host);
    let bound = local.ip();
    let allowed = if host.eq_ignore_ascii_case("localhost") {
        bound.is_loopback() || bound.is_unspecified()
    } else {
        let literal = host.trim_start_matches('[').trim_end_matches(']');
        match literal.parse::<IpAddr>() {
            Ok(ip) => {
                bound.is_unspecified() || ip == bound || (ip.is_loopback() && bound.is_loopback())
            }
            Err(_) => false,
        }
    };
    if allowed { Ok(()) } else { refuse() }
}

/// A browser names the page a request comes from in `Origin` (always for
/// WebSockets and POSTs): it must be this server's own page. Clients that
/// are not browsers send no `Origin` and pass.
pub fn check_origin(headers: &HeaderMap) -> Result<(), String> {
    let Some(origin) = headers.get(header::ORIGIN) else {
        return Ok(());
    };
    let expected = headers
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .map(|h| format!("http://{h}"));
    match (origin.to_str(), expected) {
        (Ok(origin), Some(expected)) if origin.eq_ignore_ascii_case(&expected) => Ok(()),
        _ => Err("requests from other sites' pages are refused".to_string()),
    }
}

/// `page`'s embedded files ([`assets`]), by exact path; nothing else
/// exists.
pub fn asset(page: Page, uri: &Uri) -> Response {
    match assets::find(page, uri.path()) {
        Some(asset) => (
            [(header::CONTENT_TYPE, asset.content_type)],
            Bytes::from_static(asset.bytes),
        )
            .into_response(),
        None => (StatusCode::NOT_FOUND, "not found").into_response(),
    }
}

async fn status(State(app): State<App>) -> Response {
    Json(app.shared.current().0).into_response()
}

async fn pause(State(app): State<App>) -> Response {
    app.shared.pause();
    status(State(app)).await
}

async fn resume(State(app): State<App>) -> Response {
    app.shared.resume();
    status(State(app)).await
}

async fn stop(State(app): State<App>) -> Response {
    app.shared.stop();
    status(State(app)).await
}

/// The page's drawing size (`/api/view/WIDTH/HEIGHT`, device pixels),
/// which the final picture takes.
async fn view(State(app): State<App>, Path((width, height)): Path<(u32, u32)>) -> Response {
    app.shared.set_view_size(width, height);
    StatusCode::NO_CONTENT.into_response()
}

/// The final picture ([`super::state::Status::frame`]).
async fn frame(State(app): State<App>) -> Response {
    match app.shared.frame() {
        Some(png) => ([(header::CONTENT_TYPE, "image/png")], png).into_response(),
        None => (
            StatusCode::NOT_FOUND,
            "no final picture: the solve has not ended, or --final-gather is off",
        )
            .into_response(),
    }
}

/// One vertex's data and radiosity (full precision) in the latest
/// snapshot, for the picker.
async fn vertex(State(app): State<App>, Path(index): Path<u32>) -> Response {
    let Some(scene) = app.shared.scene() else {
        return (
            StatusCode::SERVICE_UNAVAILABLE,
            "the scene is still loading",
        )
            .into_response();
    };
    let (status, snapshot) = app.shared.current();
    let (Some(info), Some(snapshot)) = (scene.vertices.get(index as usize), snapshot) else {
        return (StatusCode::NOT_FOUND, "no such vertex").into_response();
    };
    let b = snapshot.radiosity[index as usize];
    let display = b + info.rho * snapshot.ambient;
    Json(serde_json::json!({
        "index": index,
        "seq": snapshot.seq,
        "shots": status.shots,
        "position": info.position.to_array(),
        "normal": info.normal.to_array(),
        "surface": info.face,
        "reflectance": info.rho.to_array(),
        "emission": info.emission.to_array(),
        "radiosity": b.to_array(),
        "ambient": snapshot.ambient.to_array(),
        "display": display.to_array(),
    }))
    .into_response()
}

async fn live(State(app): State<App>, upgrade: WebSocketUpgrade) -> Response {
    upgrade
        .max_message_size(MAX_CLIENT_MESSAGE)
        .max_frame_size(MAX_CLIENT_MESSAGE)
        .on_upgrade(move |socket| async move {
            // A client that goes away ends its own task; nothing to report.
            let _ = feed(socket, app.shared).await;
        })
}

/// A client's feed ended: it left or the connection broke.
struct Gone;

impl From<axum::Error> for Gone {
    fn from(_: axum::Error) -> Gone {
        Gone
    }
}

/// Handles whatever the client sent while we waited; `Err` when it left.
fn client_message(message: Option<Result<Message, axum::Error>>) -> Result<(), Gone> {
    match message {
        None | Some(Err(_)) | Some(Ok(Message::Close(_))) => Err(Gone),
        // The page sends nothing else; pings are answered by the library.
        Some(Ok(_)) => Ok(()),
    }
}

/// One client: the scene, the mesh, then the status and a colour frame
/// whenever the solution changed, at most once every
/// [`SNAPSHOT_INTERVAL`], each frame carrying only what changed since the
/// client's previous one. A slow client gets fewer, never stale, frames,
/// and never slows the solve.
async fn feed(mut socket: WebSocket, shared: Arc<Shared>) -> Result<(), Gone> {
    let mut changes = shared.subscribe();
    let mut closing = shared.closing();
    if *closing.borrow() {
        return Err(Gone);
    }
    let scene = loop {
        if let Some(scene) = shared.scene() {
            break scene;
        }
        tokio::select! {
            r = changes.changed() => if r.is_err() { return Err(Gone) },
            m = socket.recv() => client_message(m)?,
            _ = closing.changed() => return close(socket).await,
        }
    };
    socket
        .send(Message::Text(scene.json.clone().into()))
        .await?;
    socket.send(Message::Binary(scene.mesh.clone())).await?;

    let mut sent: Option<(u64, Vec<Rgbe>)> = None;
    let mut last_send: Option<Instant> = None;
    changes.mark_changed();
    loop {
        tokio::select! {
            r = changes.changed() => if r.is_err() { return Err(Gone) },
            m = socket.recv() => { client_message(m)?; continue; }
            _ = closing.changed() => return close(socket).await,
        }
        if let Some(t) = last_send {
            let next = t + SNAPSHOT_INTERVAL;
            while Instant::now() < next {
                tokio::select! {
                    () = tokio::time::sleep_until(next) => {}
                    m = socket.recv() => client_message(m)?,
                    _ = closing.changed() => return close(socket).await,
                }
            }
        }
        changes.borrow_and_update();
        let (status, snapshot) = shared.current();
        let mut json = serde_json::to_value(&status).unwrap_or_default();
        json["type"] = "status".into();
        socket.send(Message::Text(json.to_string().into())).await?;
        if let Some(snapshot) = snapshot
            && sent.as_ref().is_none_or(|(seq, _)| *seq != snapshot.seq)
        {
            let current = snapshot.rgbe();
            let frame = wire::colour_frame(
                snapshot.seq,
                snapshot.ambient,
                current,
                sent.as_ref().map(|(_, c)| c.as_slice()),
            );
            socket.send(Message::Binary(frame.into())).await?;
            match &mut sent {
                Some((seq, colours)) => {
                    *seq = snapshot.seq;
                    colours.copy_from_slice(current);
                }
                None => sent = Some((snapshot.seq, current.to_vec())),
            }
        }
        last_send = Some(Instant::now());
    }
}

/// Says goodbye when the server closes.
async fn close(mut socket: WebSocket) -> Result<(), Gone> {
    socket.send(Message::Close(None)).await?;
    // Give the client a moment to answer the close, then drop it.
    let _ = tokio::time::timeout(Duration::from_millis(500), socket.recv()).await;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn headers(pairs: &[(&'static str, &str)]) -> HeaderMap {
        let mut h = HeaderMap::new();
        for (k, v) in pairs {
            h.insert(*k, HeaderValue::from_str(v).unwrap());
        }
        h
    }

    #[test]
    fn hosts() {
        let loopback: SocketAddr = "127.0.0.1:7788".parse().unwrap();
        let ok =
            |host: &str, local: SocketAddr| check_host(&headers(&[("host", host)]), local).is_ok();
        assert!(ok("127.0.0.1:7788", loopback));
        assert!(ok("localhost:7788", loopback));
        assert!(ok("LOCALHOST.:7788", loopback));
        assert!(ok("[::1]:7788", loopback));
        assert!(ok("127.0.0.2:7788", loopback));
        assert!(!ok("127.0.0.1:7789", loopback));
        assert!(!ok("127.0.0.1", loopback));
        assert!(!ok("evil.example:7788", loopback));
        assert!(!ok("localhost.evil.example:7788", loopback));
        assert!(!ok("192.168.1.5:7788", loopback));
        assert!(!ok("bad host", loopback));
        assert!(check_host(&HeaderMap::new(), loopback).is_ok());

        let all: SocketAddr = "0.0.0.0:80".parse().unwrap();
        assert!(ok("192.168.1.5", all));
        assert!(ok("localhost", all));
        assert!(!ok("evil.example", all));

        let lan: SocketAddr = "192.168.1.5:7788".parse().unwrap();
        assert!(ok("192.168.1.5:7788", lan));
        assert!(!ok("localhost:7788", lan));
        assert!(!ok("127.0.0.1:7788", lan));
    }

    #[test]
    fn origins() {
        let ok = |pairs: &[(&'static str, &str)]| check_origin(&headers(pairs)).is_ok();
        assert!(ok(&[("host", "127.0.0.1:7788")]));
        assert!(ok(&[
            ("host", "127.0.0.1:7788"),
            ("origin", "http://127.0.0.1:7788")
        ]));
        assert!(ok(&[
            ("host", "localhost:7788"),
            ("origin", "http://LOCALHOST:7788")
        ]));
        assert!(!ok(&[
            ("host", "127.0.0.1:7788"),
            ("origin", "http://evil.example")
        ]));
        assert!(!ok(&[("host", "127.0.0.1:7788"), ("origin", "null")]));
        assert!(!ok(&[
            ("host", "127.0.0.1:7788"),
            ("origin", "http://127.0.0.1:7789")
        ]));
        assert!(!ok(&[
            ("host", "127.0.0.1:7788"),
            ("origin", "https://127.0.0.1:7788")
        ]));
        assert!(!ok(&[("origin", "http://127.0.0.1:7788")]));
    }
}
