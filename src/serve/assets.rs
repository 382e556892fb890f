//! The page's files, embedded in the binary: `web/serve/` and the three.js
//! files it imports from `web/vendor/` (see web/README.md). The server
//! reads no file at run time, so no request can reach the disk.

/// One embedded file.
#[derive(Clone, Copy, Debug)]
pub struct Asset {
    /// Its URL path.
    pub path: &'static str,
    /// Its `Content-Type`.
    pub content_type: &'static str,
    /// Its contents.
    pub bytes: &'static [u8],
}

const JS: &str = "text/javascript; charset=utf-8";

/// Every file the server can send.
pub const ASSETS: [Asset; 5] = [
    Asset {
        path: "/",
        content_type: "text/html; charset=utf-8",
        bytes: include_bytes!("../../web/serve/index.html"),
    },
    Asset {
        path: "/serve.js",
        content_type: JS,
        bytes: include_bytes!("../../web/serve/serve.js"),
    },
    Asset {
        path: "/vendor/three/build/three.module.js",
        content_type: JS,
        bytes: include_bytes!("../../web/vendor/three/build/three.module.js"),
    },
    Asset {
        path: "/vendor/three/build/three.core.js",
        content_type: JS,
        bytes: include_bytes!("../../web/vendor/three/build/three.core.js"),
    },
    Asset {
        path: "/vendor/three/examples/jsm/controls/OrbitControls.js",
        content_type: JS,
        bytes: include_bytes!("../../web/vendor/three/examples/jsm/controls/OrbitControls.js"),
    },
];

/// The file at exactly `path` (`/index.html` is `/`).
#[must_use]
pub fn find(path: &str) -> Option<&'static Asset> {
    let path = if path == "/index.html" { "/" } else { path };
    ASSETS.iter().find(|a| a.path == path)
}
