//! `radiosity view`: serves the bake viewer page (`web/viewer/`, three.js
//! embedded in the binary, nothing fetched from elsewhere) and one baked
//! glTF file on 127.0.0.1, so a bake can be looked at in any browser
//! (beyond the paper: its radiosity, baked as Wallace, Elmquist & Haines
//! 1989 display it, shaded per vertex).
//!
//! The same server as the live view's (axum, [`super::http`]'s guard
//! against other hosts and sites, the one table of embedded files,
//! [`super::assets`]) with two routes: the page's files, and
//! `GET /model/NAME`, a plain file beside the model (the model itself, a
//! `.gltf`'s buffers and images), read from disk on every request so a
//! re-bake shows on reload. Nothing outside the model's folder is served.

use std::net::{Ipv4Addr, SocketAddr};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use axum::Router;
use axum::extract::{Path as UrlPath, State};
use axum::http::{StatusCode, Uri, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;

use super::Error;
use super::assets::Page;
use super::http::{Guard, asset};

/// The viewer page's content security policy: the live view's, with
/// `blob:` images (three.js's glTF loader hands a `.glb`'s embedded
/// textures to the browser as blobs).
const VIEWER_POLICY: &str = "default-src 'self'; script-src 'self' 'unsafe-inline'; \
     style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; connect-src 'self' blob:; \
     frame-ancestors 'none'; base-uri 'none'; form-action 'none'";

/// A viewer server bound to a port.
pub struct Viewer {
    runtime: tokio::runtime::Runtime,
    listener: tokio::net::TcpListener,
    local: SocketAddr,
    folder: PathBuf,
    model: String,
}

/// Why `radiosity view` cannot serve a file.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// Not a glTF file name.
    #[error("{0}: the file name must end in .glb or .gltf")]
    NotGltf(PathBuf),
    /// No such file.
    #[error("{0}: no such file")]
    Missing(PathBuf),
    /// A file name that is not UTF-8.
    #[error("{0}: the file name is not UTF-8")]
    Name(PathBuf),
    /// The server would not start.
    #[error(transparent)]
    Server(#[from] Error),
}

impl Viewer {
    /// Binds 127.0.0.1:`port` (0: any free port) to serve `model`, which
    /// must be a `.glb` or `.gltf` file; a `.gltf`'s buffers and images are
    /// served from its folder.
    ///
    /// # Errors
    ///
    /// A file that is not glTF or not there, or a port that cannot be
    /// bound.
    pub fn bind(model: &Path, port: u16) -> Result<Viewer, ViewError> {
        if !radiosity::scene::is_gltf(model) {
            return Err(ViewError::NotGltf(model.to_path_buf()));
        }
        if !model.is_file() {
            return Err(ViewError::Missing(model.to_path_buf()));
        }
        let name = model
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| ViewError::Name(model.to_path_buf()))?
            .to_string();
        let folder = match model.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let address = SocketAddr::from((Ipv4Addr::LOCALHOST, port));
        let (runtime, listener, local) = super::listen(address, "radiosity-view")?;
        Ok(Viewer {
            runtime,
            listener,
            local,
            folder,
            model: name,
        })
    }

    /// The page's address, with the model to show.
    #[must_use]
    pub fn url(&self) -> String {
        format!(
            "http://{}/?model=/model/{}",
            self.local,
            encode(&self.model)
        )
    }

    /// Serves until the process ends.
    ///
    /// # Errors
    ///
    /// When the listener fails.
    pub fn run(self) -> std::io::Result<()> {
        let app = router(Arc::new(self.folder), self.local);
        let listener = self.listener;
        self.runtime
            .block_on(async move { axum::serve(listener, app).await })
    }
}

/// The viewer's routes for the model's `folder`, on a server listening on
/// `local`.
fn router(folder: Arc<PathBuf>, local: SocketAddr) -> Router {
    let routes = Router::new()
        .route("/model/{name}", get(model_file))
        .fallback(get(|uri: Uri| async move { asset(Page::Viewer, &uri) }));
    Guard {
        local,
        policy: VIEWER_POLICY,
    }
    .around(routes)
    .with_state(folder)
}

/// A plain file beside the model: no folders, no `..`.
async fn model_file(
    State(folder): State<Arc<PathBuf>>,
    UrlPath(name): UrlPath<String>,
) -> Response {
    if name.is_empty() || name.contains(['/', '\\']) || name == ".." || name == "." {
        return (StatusCode::NOT_FOUND, "not found").into_response();
    }
    let path = folder.join(&name);
    let read = tokio::task::spawn_blocking(move || std::fs::read(path)).await;
    match read {
        Ok(Ok(bytes)) => ([(header::CONTENT_TYPE, mime_of(&name))], bytes).into_response(),
        _ => (StatusCode::NOT_FOUND, "not found").into_response(),
    }
}

/// Percent-encodes a file name for a URL path.
fn encode(name: &str) -> String {
    name.bytes()
        .map(|b| {
            if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
                (b as char).to_string()
            } else {
                format!("%{b:02X}")
            }
        })
        .collect()
}

fn mime_of(name: &str) -> &'static str {
    let lower = name.to_ascii_lowercase();
    if lower.ends_with(".glb") {
        "model/gltf-binary"
    } else if lower.ends_with(".gltf") {
        "model/gltf+json"
    } else if lower.ends_with(".png") {
        "image/png"
    } else if lower.ends_with(".jpg") || lower.ends_with(".jpeg") {
        "image/jpeg"
    } else {
        "application/octet-stream"
    }
}

#[cfg(test)]
mod tests {
    use std::io::{Read, Write};
    use std::net::TcpStream;

    use super::*;

    /// The page, three.js and the model are served (GET and HEAD); nothing
    /// outside the model's folder is, nor the live view's page, nor to a
    /// page of another site.
    #[test]
    fn serves_page_library_and_model_only() {
        let dir = tempfile::tempdir().unwrap();
        let model = dir.path().join("my bake.glb");
        std::fs::write(&model, b"glTF-bytes").unwrap();
        std::fs::write(dir.path().join("..secret"), b"no").unwrap();
        let viewer = Viewer::bind(&model, 0).unwrap();
        let port = viewer.local.port();
        let url = viewer.url();
        assert!(url.ends_with("/?model=/model/my%20bake.glb"), "{url}");
        std::thread::spawn(move || viewer.run());
        let request = |head: &str| -> String {
            let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
            write!(
                s,
                "{head}\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
            )
            .unwrap();
            let mut out = String::new();
            s.read_to_string(&mut out).unwrap();
            out
        };
        let get = |path: &str| request(&format!("GET {path} HTTP/1.1"));
        let page = get("/");
        assert!(page.starts_with("HTTP/1.1 200"), "{page}");
        assert!(page.contains("importmap") && page.contains("viewer.js"));
        assert!(get("/vendor/three/build/three.module.js").starts_with("HTTP/1.1 200"));
        assert!(
            get("/vendor/three/examples/jsm/loaders/GLTFLoader.js").starts_with("HTTP/1.1 200")
        );
        let m = get("/model/my%20bake.glb");
        assert!(
            m.starts_with("HTTP/1.1 200") && m.ends_with("glTF-bytes"),
            "{m}"
        );
        assert!(
            m.to_ascii_lowercase()
                .contains("content-type: model/gltf-binary"),
            "{m}"
        );
        let head = request("HEAD /model/my%20bake.glb HTTP/1.1");
        assert!(
            head.starts_with("HTTP/1.1 200") && !head.ends_with("glTF-bytes"),
            "{head}"
        );
        assert!(get("/model/..%2F..secret").starts_with("HTTP/1.1 404"));
        assert!(get("/model/%2E%2E").starts_with("HTTP/1.1 404"));
        assert!(get("/model/missing.glb").starts_with("HTTP/1.1 404"));
        assert!(get("/serve.js").starts_with("HTTP/1.1 404"));
        assert!(request("POST / HTTP/1.1").starts_with("HTTP/1.1 405"));
        let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
        write!(
            s,
            "GET / HTTP/1.1\r\nHost: evil.example:{port}\r\nConnection: close\r\n\r\n"
        )
        .unwrap();
        let mut out = String::new();
        s.read_to_string(&mut out).unwrap();
        assert!(out.starts_with("HTTP/1.1 403"), "{out}");
    }

    #[test]
    fn names_are_percent_encoded() {
        assert_eq!(encode("my bake.glb"), "my%20bake.glb");
        assert_eq!(encode("a/b"), "a%2Fb");
    }
}
