//! `radiosity view`: serves the bake viewer page (`web/viewer/`, three.js
//! embedded in the binary, nothing fetched from elsewhere) and one baked
//! glTF file on 127.0.0.1, so a bake can be looked at in any browser.
//!
//! A deliberately small static HTTP/1.1 server: GET and HEAD only, one
//! response per connection, loopback only. The model is read from disk on
//! every request, so a re-bake shows on reload.

use std::io::{self, BufRead, BufReader, Write};
use std::net::{Ipv4Addr, TcpListener, TcpStream};
use std::path::{Path, PathBuf};

/// The embedded files: URL path, MIME type, contents.
const FILES: [(&str, &str, &str); 8] = [
    (
        "/",
        "text/html; charset=utf-8",
        include_str!("../web/viewer/index.html"),
    ),
    (
        "/viewer.js",
        "text/javascript; charset=utf-8",
        include_str!("../web/viewer/viewer.js"),
    ),
    (
        "/vendor/three/build/three.module.js",
        "text/javascript; charset=utf-8",
        include_str!("../web/vendor/three/build/three.module.js"),
    ),
    (
        "/vendor/three/build/three.core.js",
        "text/javascript; charset=utf-8",
        include_str!("../web/vendor/three/build/three.core.js"),
    ),
    (
        "/vendor/three/examples/jsm/loaders/GLTFLoader.js",
        "text/javascript; charset=utf-8",
        include_str!("../web/vendor/three/examples/jsm/loaders/GLTFLoader.js"),
    ),
    (
        "/vendor/three/examples/jsm/controls/OrbitControls.js",
        "text/javascript; charset=utf-8",
        include_str!("../web/vendor/three/examples/jsm/controls/OrbitControls.js"),
    ),
    (
        "/vendor/three/examples/jsm/utils/BufferGeometryUtils.js",
        "text/javascript; charset=utf-8",
        include_str!("../web/vendor/three/examples/jsm/utils/BufferGeometryUtils.js"),
    ),
    (
        "/vendor/three/examples/jsm/utils/SkeletonUtils.js",
        "text/javascript; charset=utf-8",
        include_str!("../web/vendor/three/examples/jsm/utils/SkeletonUtils.js"),
    ),
];

/// Longest request head read, in bytes.
const MAX_REQUEST: usize = 16 * 1024;

/// A viewer server bound to a port.
pub struct Server {
    listener: TcpListener,
    folder: PathBuf,
    model: String,
}

impl Server {
    /// Binds 127.0.0.1:`port` (0: any free port) to serve `model`, which
    /// must be a `.glb` or `.gltf` file; a `.gltf`'s buffers and images are
    /// served from its folder.
    pub fn bind(model: &Path, port: u16) -> io::Result<Server> {
        if !radiosity::scene::is_gltf(model) {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "{}: the file name must end in .glb or .gltf",
                    model.display()
                ),
            ));
        }
        if !model.is_file() {
            return Err(io::Error::new(
                io::ErrorKind::NotFound,
                format!("{}: no such file", model.display()),
            ));
        }
        let name = model
            .file_name()
            .and_then(|n| n.to_str())
            .ok_or_else(|| io::Error::other("the file name is not UTF-8"))?
            .to_string();
        let folder = match model.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let listener = TcpListener::bind((Ipv4Addr::LOCALHOST, port)).map_err(|e| {
            io::Error::new(e.kind(), format!("cannot listen on 127.0.0.1:{port}: {e}"))
        })?;
        Ok(Server {
            listener,
            folder,
            model: name,
        })
    }

    /// The page's address, with the model to show.
    #[must_use]
    pub fn url(&self) -> String {
        let port = self.listener.local_addr().map_or(0, |a| a.port());
        format!(
            "http://127.0.0.1:{port}/?model=/model/{}",
            encode(&self.model)
        )
    }

    /// Serves until the process ends.
    pub fn run(&self) -> io::Result<()> {
        for stream in self.listener.incoming() {
            let Ok(stream) = stream else { continue };
            let folder = self.folder.clone();
            std::thread::spawn(move || {
                // A client that goes away mid-request is not our problem.
                let _ = respond(stream, &folder);
            });
        }
        Ok(())
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

/// Decodes `%XX` escapes; `None` if the result is not UTF-8.
fn decode(path: &str) -> Option<String> {
    let bytes = path.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' && i + 3 <= bytes.len() {
            let v = u8::from_str_radix(std::str::from_utf8(&bytes[i + 1..i + 3]).ok()?, 16).ok()?;
            out.push(v);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
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

fn respond(stream: TcpStream, folder: &Path) -> io::Result<()> {
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut head = String::new();
    let mut request_line = String::new();
    reader.read_line(&mut request_line)?;
    // Skip the headers; nothing in them matters here.
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line)? == 0 || line == "\r\n" || line == "\n" {
            break;
        }
        head.push_str(&line);
        if head.len() > MAX_REQUEST {
            return send(
                stream,
                431,
                "text/plain",
                b"request header too large",
                false,
            );
        }
    }
    let mut parts = request_line.split_whitespace();
    let method = parts.next().unwrap_or("");
    let target = parts.next().unwrap_or("");
    let with_body = method == "GET";
    if method != "GET" && method != "HEAD" {
        return send(stream, 405, "text/plain", b"only GET and HEAD", false);
    }
    let path = target.split('?').next().unwrap_or("/");
    if let Some((_, mime, body)) = FILES.iter().find(|(p, _, _)| *p == path) {
        return send(stream, 200, mime, body.as_bytes(), with_body);
    }
    if let Some(name) = path.strip_prefix("/model/").and_then(decode) {
        // Only plain file names beside the model: no folders, no '..'.
        if !name.is_empty() && !name.contains(['/', '\\']) && name != ".." && name != "." {
            return match std::fs::read(folder.join(&name)) {
                Ok(bytes) => send(stream, 200, mime_of(&name), &bytes, with_body),
                Err(_) => send(stream, 404, "text/plain", b"not found", with_body),
            };
        }
    }
    send(stream, 404, "text/plain", b"not found", with_body)
}

fn send(
    mut stream: TcpStream,
    status: u16,
    mime: &str,
    body: &[u8],
    with_body: bool,
) -> io::Result<()> {
    let reason = match status {
        200 => "OK",
        404 => "Not Found",
        405 => "Method Not Allowed",
        _ => "Request Header Fields Too Large",
    };
    write!(
        stream,
        "HTTP/1.1 {status} {reason}\r\nContent-Type: {mime}\r\nContent-Length: {}\r\n\
         Cache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    )?;
    if with_body {
        stream.write_all(body)?;
    }
    stream.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_through_urls() {
        assert_eq!(encode("my bake.glb"), "my%20bake.glb");
        assert_eq!(decode("my%20bake.glb").as_deref(), Some("my bake.glb"));
        assert_eq!(decode("bad%zz"), None);
    }

    /// The page, three.js and the model are served; nothing outside the
    /// model's folder is.
    #[test]
    fn serves_page_library_and_model_only() {
        let dir = tempfile::tempdir().unwrap();
        let model = dir.path().join("bake.glb");
        std::fs::write(&model, b"glTF-bytes").unwrap();
        let server = Server::bind(&model, 0).unwrap();
        let port = server.listener.local_addr().unwrap().port();
        let folder = server.folder.clone();
        let listener = server.listener.try_clone().unwrap();
        std::thread::spawn(move || {
            for stream in listener.incoming().flatten() {
                let _ = respond(stream, &folder);
            }
        });
        let get = |path: &str| -> String {
            use std::io::Read;
            let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
            write!(s, "GET {path} HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
            let mut out = String::new();
            s.read_to_string(&mut out).unwrap();
            out
        };
        assert!(get("/").starts_with("HTTP/1.1 200"));
        assert!(get("/").contains("importmap"));
        assert!(get("/vendor/three/build/three.module.js").starts_with("HTTP/1.1 200"));
        let m = get("/model/bake.glb");
        assert!(
            m.starts_with("HTTP/1.1 200") && m.ends_with("glTF-bytes"),
            "{m}"
        );
        assert!(get("/model/..%2Fsecret").starts_with("HTTP/1.1 404"));
        assert!(get("/model/missing.glb").starts_with("HTTP/1.1 404"));
        assert!(server.url().ends_with("/?model=/model/bake.glb"));
    }
}
