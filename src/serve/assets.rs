//! The one table of the pages' files, embedded in the binary: the live
//! view's (`web/serve/`), the bake viewer's (`web/viewer/`) and the three.js
//! files they import from `web/vendor/` (see web/README.md). The servers
//! read none of them at run time, so no request for one can reach the disk.

/// Which server's page a file belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Page {
    /// `radiosity serve`'s.
    Live,
    /// `radiosity view`'s.
    Viewer,
    /// Both (the three.js files).
    Both,
}

/// One embedded file.
#[derive(Clone, Copy, Debug)]
pub struct Asset {
    /// The page it belongs to.
    pub page: Page,
    /// Its URL path.
    pub path: &'static str,
    /// Its `Content-Type`.
    pub content_type: &'static str,
    /// Its contents.
    pub bytes: &'static [u8],
}

const JS: &str = "text/javascript; charset=utf-8";
const HTML: &str = "text/html; charset=utf-8";

/// Every file the server can send.
pub const ASSETS: [Asset; 10] = [
    Asset {
        page: Page::Live,
        path: "/",
        content_type: HTML,
        bytes: include_bytes!("../../web/serve/index.html"),
    },
    Asset {
        page: Page::Live,
        path: "/serve.js",
        content_type: JS,
        bytes: include_bytes!("../../web/serve/serve.js"),
    },
    Asset {
        page: Page::Viewer,
        path: "/",
        content_type: HTML,
        bytes: include_bytes!("../../web/viewer/index.html"),
    },
    Asset {
        page: Page::Viewer,
        path: "/viewer.js",
        content_type: JS,
        bytes: include_bytes!("../../web/viewer/viewer.js"),
    },
    Asset {
        page: Page::Viewer,
        path: "/vendor/three/examples/jsm/loaders/GLTFLoader.js",
        content_type: JS,
        bytes: include_bytes!("../../web/vendor/three/examples/jsm/loaders/GLTFLoader.js"),
    },
    Asset {
        page: Page::Viewer,
        path: "/vendor/three/examples/jsm/utils/BufferGeometryUtils.js",
        content_type: JS,
        bytes: include_bytes!("../../web/vendor/three/examples/jsm/utils/BufferGeometryUtils.js"),
    },
    Asset {
        page: Page::Viewer,
        path: "/vendor/three/examples/jsm/utils/SkeletonUtils.js",
        content_type: JS,
        bytes: include_bytes!("../../web/vendor/three/examples/jsm/utils/SkeletonUtils.js"),
    },
    Asset {
        page: Page::Both,
        path: "/vendor/three/build/three.module.js",
        content_type: JS,
        bytes: include_bytes!("../../web/vendor/three/build/three.module.js"),
    },
    Asset {
        page: Page::Both,
        path: "/vendor/three/build/three.core.js",
        content_type: JS,
        bytes: include_bytes!("../../web/vendor/three/build/three.core.js"),
    },
    Asset {
        page: Page::Both,
        path: "/vendor/three/examples/jsm/controls/OrbitControls.js",
        content_type: JS,
        bytes: include_bytes!("../../web/vendor/three/examples/jsm/controls/OrbitControls.js"),
    },
];

/// `page`'s file at exactly `path` (`/index.html` is `/`).
#[must_use]
pub fn find(page: Page, path: &str) -> Option<&'static Asset> {
    let path = if path == "/index.html" { "/" } else { path };
    ASSETS
        .iter()
        .find(|a| (a.page == page || a.page == Page::Both) && a.path == path)
}
