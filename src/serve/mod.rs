//! `radiosity serve`: the solution converging live in a browser, the way
//! progressive refinement was meant to be watched (Cohen, Chen, Wallace &
//! Greenberg, *A Progressive Refinement Approach to Fast Radiosity Image
//! Generation*, SIGGRAPH 1988; Wong & Tsang's Figure 5.1 shows their room
//! after 9, 48 and 72 subsources). A local web server shows the element mesh with
//! Gouraud-shaded vertex colours from the scene's camera, updated a few
//! times a second while the solve runs, with the page's controls: pause and
//! resume, stop (the outputs asked for on the command line are then written
//! from the state reached), the ambient term on or off, an exposure slider,
//! and a picker that shows one vertex's radiosity. Pause takes effect when
//! the current shot ends (a shot of a large scene can take a while on a
//! small machine), or before the first shot when pressed while loading;
//! stop abandons the current shot. `--pause-at 10,100` also pauses the
//! solve by itself after those many shots (0: before the first), as the
//! pause button would, to look at the solution at known points of its
//! progress, or to hold a solve at a known shot for a test; resume goes on
//! to the next. Time held paused counts neither in the page's solve time
//! nor against `--time-limit`.
//!
//! The same server, with the same guard and table of embedded files,
//! serves `radiosity view`'s bake viewer ([`viewer`]).
//!
//! # Threads
//! The solve runs on the caller's thread through [`radiosity::app::run`] with
//! the [`Server::observer`], at full speed whether or not a page is open:
//! after a shot it copies the vertex radiosities into shared state at most
//! every [`state::SNAPSHOT_INTERVAL`] (250 ms) of solve time, and whenever it
//! pauses, and never waits on the network; it blocks only while paused.
//! The server (axum on a one-thread tokio runtime) feeds every client from
//! the latest snapshot; a client that
//! connects late gets the current state, a slow one gets fewer frames, and
//! closing the page does not stop the solve. Once the solve has ended
//! (converged, stopped, or a limit reached) and the outputs are written,
//! the final state is served until Ctrl-C.
//!
//! # Ctrl-C
//! [`Handle::shutdown`] (the binary calls it on Ctrl-C, SIGTERM or SIGHUP):
//! a solve still running stops (its current shot abandoned), the outputs are
//! written from the state reached (as with the stop button: no work is
//! lost, and nothing is half written), then the server closes its
//! connections and the command exits with status 0. After the solve has
//! ended it just closes. The binary exits at once (status 130) on a second
//! Ctrl-C.
//!
//! # Routes
//! | route | what |
//! | --- | --- |
//! | `GET /` | the page (`web/serve/index.html`) |
//! | `GET /serve.js`, `GET /vendor/three/...` | its script and three.js 0.187.0, embedded |
//! | `GET /api/live` | WebSocket: the messages below |
//! | `GET /api/status` | the status message as JSON |
//! | `GET /api/vertex/{i}` | vertex `i`: position, normal, surface (input face), reflectance, emission, radiosity `B` (W/m^2, full precision), the ambient term, and `B + rho ambient` |
//! | `POST /api/pause`, `/api/resume`, `/api/stop` | the controls; answer the status |
//! | `POST /api/view/{width}/{height}` | the size the page draws at, device pixels (16 to 4096 a side): the final picture's size |
//! | `GET /api/frame.png` | once the solve has ended, with the final pass on: the solution drawn from the scene's view with it (the status's `frame` gives its size); 404 before |
//!
//! # Messages on `/api/live`
//! In order: one text message with the scene (JSON: `type: "scene"`,
//! name, counts, bounds, `camera` {`eye`, `target`, `up`, `fov`
//! (vertical, degrees)}, the initial `ambient` switch and `exposure` in
//! stops); one binary mesh message; then, whenever the solution or the
//! status changed and at most every [`state::SNAPSHOT_INTERVAL`], a text status
//! message (JSON: `type: "status"`, `phase` (loading, solving, paused,
//! writing, finished), `seq`, `shots`, `subsources`, `rays`,
//! `rays_per_second`, `unshot_fraction`, `elapsed_seconds` (pauses
//! excluded), `pause_requested`, `stop_requested`, `stop_reason`,
//! `written`, `device`, `device_shots`, `frame`: the final picture's
//! `[width, height]` once drawn, else null; `final_pass`: while the
//! outputs are made, `{what, done, total}` of the final pass (`total` 0
//! where not known beforehand), else null), followed at once by a binary colour frame when its `seq`
//! is not that of the client's previous frame (`seq` 0: nothing to show
//! yet).
//! All binary numbers are little-endian; every array starts on a multiple
//! of 4 bytes, so a browser reads them with typed-array views.
//!
//! Mesh message ([`wire::mesh_message`]):
//!
//! | offset | type | field |
//! | --- | --- | --- |
//! | 0 | 4 bytes | `RMSH` |
//! | 4 | u32 | `V`, vertices |
//! | 8 | u32 | `T`, triangles |
//! | 12 | f32 x 3V | positions, metres |
//! | 12 + 12V | f32 x 3V | reflectance `rho` of each vertex's surface |
//! | 12 + 24V | u32 x 3T | triangles (elements, quads split in two), counter-clockwise from the front |
//!
//! Colour frame ([`wire::colour_frame`]):
//!
//! | offset | type | field |
//! | --- | --- | --- |
//! | 0 | 4 bytes | `RCOL` |
//! | 4 | u32 | `seq`, the snapshot (matches the status sent just before) |
//! | 8 | u32 | `n`, vertices in this frame |
//! | 12 | u32 | flags: bit 0 set = full frame (all `V` vertices in order, no indices) |
//! | 16 | f32 x 3 | the ambient term, W/m^2 |
//! | 28 | u32 x n | the vertices whose colour changed since the client's previous frame, ascending (absent in a full frame) |
//! | 28 + 4n (28 if full) | 4 bytes x n | their radiosity `B` in Ward's RGBE: `(byte + 0.5) 2^(e - 136)` W/m^2 per channel, 0 when `e` = 0 |
//!
//! A client's first frame is full; later ones carry only the vertices
//! whose RGBE bytes changed (full again when that is more than half).
//!
//! # What the page shows
//! Each vertex's displayed radiosity is `B + rho ambient` with the ambient
//! term of Cohen et al. (1988) on, `B` with it off, Gouraud-interpolated in
//! linear light and tone-mapped per pixel like the pictures of
//! [`radiosity::render`]: scaled so the 90th percentile of the luminance of the
//! covered pixels maps to 0.8, then by the slider's stops, then clamped and
//! sRGB-encoded. The percentile is taken (on the GPU, at reduced size, from
//! the current view, again whenever the view stops moving) from the
//! picture *with* the ambient term, an estimate of the converged
//! picture, whichever is shown: the exposure then holds still while the
//! solution converges, so the picture without the ambient term visibly
//! brightens; once converged the ambient term is negligible and the
//! exposure is that of the written picture from the same view.
//!
//! # Security
//! The server binds to 127.0.0.1 unless told otherwise, serves only the
//! embedded files and the live state (no route reads a file or takes a
//! path), refuses requests whose `Host` is not this server (DNS rebinding)
//! or whose `Origin` is another site (cross-site requests and WebSockets),
//! and forbids framing.

mod assets;
mod http;
mod observer;
mod state;
pub mod viewer;
pub mod wire;

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

pub use observer::LiveObserver;
pub use state::Display;

use radiosity::app::Outcome;

/// The default `--port`.
pub const DEFAULT_PORT: u16 = 7788;

/// Why the server could not run.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The address could not be bound.
    #[error("cannot listen on {address}: {source} (--port 0 takes any free port)")]
    Bind {
        /// The address asked for.
        address: SocketAddr,
        /// What the operating system said.
        source: std::io::Error,
    },
    /// The server's runtime could not start.
    #[error("cannot start the web server: {0}")]
    Runtime(std::io::Error),
}

/// Cancels a run from another thread (a Ctrl-C handler).
#[derive(Clone)]
pub struct Handle {
    shared: Arc<state::Shared>,
}

impl Handle {
    /// Stops the solve if it still runs (its outputs are then written) and
    /// lets [`Server::wait`] return.
    pub fn shutdown(&self) {
        self.shared.request_shutdown();
    }
}

/// A running live-view server.
pub struct Server {
    runtime: tokio::runtime::Runtime,
    shared: Arc<state::Shared>,
    local: SocketAddr,
    serving: tokio::task::JoinHandle<std::io::Result<()>>,
}

/// A one-thread runtime named `thread` and a listener bound to `address`
/// (port 0: any free port) on it, with the address it got: what both
/// servers (the live view, the bake viewer) start from.
pub(crate) fn listen(
    address: SocketAddr,
    thread: &str,
) -> Result<(tokio::runtime::Runtime, tokio::net::TcpListener, SocketAddr), Error> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .thread_name(thread)
        .enable_io()
        .enable_time()
        .build()
        .map_err(Error::Runtime)?;
    let listener = runtime
        .block_on(tokio::net::TcpListener::bind(address))
        .map_err(|source| Error::Bind { address, source })?;
    let local = listener
        .local_addr()
        .map_err(|source| Error::Bind { address, source })?;
    Ok((runtime, listener, local))
}

impl Server {
    /// Binds `address` (port 0: any free port) and starts serving; the
    /// page shows "loading" until [`Server::observer`] is told the mesh.
    /// The solve pauses by itself once it has made each of `pause_at`
    /// shots (0: before the first).
    pub fn start(address: SocketAddr, display: Display, pause_at: &[u64]) -> Result<Server, Error> {
        let (runtime, listener, local) = listen(address, "radiosity-serve")?;
        let shared = Arc::new(state::Shared::new(display, pause_at));
        let router = http::router(shared.clone(), local);
        let mut closing = shared.closing();
        let serving = runtime.spawn(async move {
            axum::serve(listener, router)
                .with_graceful_shutdown(async move {
                    // An error means the sender is gone: close too.
                    let _ = closing.wait_for(|c| *c).await;
                })
                .await
        });
        Ok(Server {
            runtime,
            shared,
            local,
            serving,
        })
    }

    /// The page's address, `http://ADDRESS:PORT/`.
    #[must_use]
    pub fn url(&self) -> String {
        format!("http://{}/", self.local)
    }

    /// The observer to pass to [`radiosity::app::run`].
    #[must_use]
    pub fn observer(&self) -> LiveObserver {
        LiveObserver::new(self.shared.clone())
    }

    /// A handle for a Ctrl-C handler.
    #[must_use]
    pub fn handle(&self) -> Handle {
        Handle {
            shared: self.shared.clone(),
        }
    }

    /// Whether [`Handle::shutdown`] was called.
    #[must_use]
    pub fn shutdown_requested(&self) -> bool {
        self.shared.shutdown_requested()
    }

    /// The run is over and its outputs written: the page says so and lists
    /// them.
    pub fn finished(&self, outcome: &Outcome) {
        self.shared.finished(outcome);
    }

    /// Serves until [`Handle::shutdown`], then closes.
    pub fn wait(self) {
        let shared = self.shared.clone();
        self.runtime.block_on(async move {
            let mut changes = shared.subscribe();
            while !shared.shutdown_requested() {
                if changes.changed().await.is_err() {
                    break;
                }
            }
        });
        self.close();
    }

    /// Closes every connection and stops serving.
    pub fn close(self) {
        self.shared.close();
        let serving = self.serving;
        // Connections get a moment to say goodbye; the runtime's shutdown
        // ends whatever is left.
        let _ = self
            .runtime
            .block_on(async { tokio::time::timeout(Duration::from_secs(2), serving).await });
        self.runtime.shutdown_timeout(Duration::from_secs(1));
    }
}
