//! `radiosity serve` without a browser: the address it prints, the files it
//! serves (and the ones it must not), the host and origin checks, the live
//! WebSocket messages decoded from their documented layout against the
//! solver's own output (the vertex CSV written on stop), pause, stop,
//! Ctrl-C, and the loopback binding. The page itself is tested in headless
//! Chromium by web/test/serve.test.mjs.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use approx::{abs_diff_eq, assert_abs_diff_eq};
use serde_json::Value;
use tungstenite::Message;
use tungstenite::client::IntoClientRequest;

/// A solve of the Cornell box thousands of shots long (1,863 to
/// `--converge 1e-9`: a few seconds here, far less on a fast machine). A
/// test that must find the solve still running when it acts holds it at a
/// known shot with `--pause-at` (the tests below never depend on how fast
/// the machine is); the others assert nothing that depends on whether it
/// ended before they stopped it.
const LONG_SOLVE: [&str; 4] = ["--converge", "1e-9", "--threads", "1"];

/// Longest any wait in these tests may take: a safety net far above what
/// any of them needs, even on one busy core.
const PATIENCE: Duration = Duration::from_secs(300);

/// A running `radiosity serve`, killed if the test fails before it exits.
struct Served {
    child: Child,
    address: SocketAddr,
    dir: tempfile::TempDir,
    stderr: mpsc::Receiver<String>,
}

impl Served {
    /// Starts `radiosity serve cornell ARGS --port 0` writing a picture, a
    /// vertex CSV and statistics into a fresh folder.
    fn start(args: &[&str]) -> Served {
        let dir = tempfile::tempdir().unwrap();
        let mut command = Command::new(env!("CARGO_BIN_EXE_radiosity"));
        command.env("RADIOSITY_DEVICE", "cpu");
        command
            .args([
                "serve", "cornell", "--port", "0", "--width", "64", "--height", "48",
            ])
            .arg("--output")
            .arg(dir.path().join("out.png"))
            .arg("--vertices")
            .arg(dir.path().join("out.csv"))
            .arg("--stats")
            .arg(dir.path().join("out.json"))
            .args(args);
        Served::spawn(command, dir)
    }

    fn spawn(mut command: Command, dir: tempfile::TempDir) -> Served {
        let mut child = command
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (lines, first) = mpsc::channel();
        let stdout = child.stdout.take().unwrap();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                let _ = lines.send(line);
            }
        });
        let (errors, stderr) = mpsc::channel();
        let mut pipe = child.stderr.take().unwrap();
        std::thread::spawn(move || {
            let mut text = String::new();
            let _ = pipe.read_to_string(&mut text);
            let _ = errors.send(text);
        });
        let line = first
            .recv_timeout(PATIENCE)
            .expect("radiosity serve printed no address");
        let address = line
            .strip_prefix("serving http://")
            .and_then(|rest| rest.strip_suffix('/'))
            .unwrap_or_else(|| panic!("unexpected first line {line:?}"))
            .parse()
            .unwrap();
        Served {
            child,
            address,
            dir,
            stderr,
        }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    fn get(&self, path: &str) -> Response {
        request(self.address, "GET", path, &[])
    }

    fn post(&self, path: &str) -> Response {
        request(self.address, "POST", path, &[])
    }

    fn status(&self) -> Value {
        let r = self.get("/api/status");
        assert_eq!(r.status, 200);
        serde_json::from_slice(&r.body).unwrap()
    }

    /// Polls the status until `done` holds.
    fn wait_for(&self, what: &str, done: impl Fn(&Value) -> bool) -> Value {
        let start = Instant::now();
        loop {
            let status = self.status();
            if done(&status) {
                return status;
            }
            assert!(
                start.elapsed() < PATIENCE,
                "waited too long for {what}: {status}"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn wait_finished(&self) -> Value {
        self.wait_for("the end of the run", |s| s["phase"] == "finished")
    }

    /// Sends SIGINT, as Ctrl-C does.
    fn interrupt(&self) {
        let ok = Command::new("kill")
            .args(["-INT", &self.child.id().to_string()])
            .status()
            .unwrap()
            .success();
        assert!(ok);
    }

    /// Waits for the process to exit by itself.
    fn exit(&mut self) -> (ExitStatus, String) {
        let start = Instant::now();
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                let stderr = self.stderr.recv_timeout(PATIENCE).unwrap_or_default();
                return (status, stderr);
            }
            assert!(start.elapsed() < PATIENCE, "radiosity serve did not exit");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn websocket(&self) -> Live {
        let stream = TcpStream::connect(self.address).unwrap();
        stream.set_read_timeout(Some(PATIENCE)).unwrap();
        let (socket, _) =
            tungstenite::client(format!("ws://{}/api/live", self.address), stream).unwrap();
        Live {
            socket,
            last_seq: None,
        }
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

struct Response {
    status: u16,
    head: String,
    body: Vec<u8>,
}

impl Response {
    fn header(&self, name: &str) -> Option<&str> {
        self.head.lines().find_map(|line| {
            let (k, v) = line.split_once(':')?;
            k.eq_ignore_ascii_case(name).then(|| v.trim())
        })
    }
}

/// One HTTP/1.1 request written by hand, so that paths reach the server
/// exactly as written (clients normalise `..`).
fn request(address: SocketAddr, method: &str, path: &str, headers: &[(&str, String)]) -> Response {
    let mut stream = TcpStream::connect(address).unwrap();
    stream.set_read_timeout(Some(PATIENCE)).unwrap();
    let mut text =
        format!("{method} {path} HTTP/1.1\r\nConnection: close\r\nContent-Length: 0\r\n");
    if !headers.iter().any(|(k, _)| k.eq_ignore_ascii_case("host")) {
        text += &format!("Host: {address}\r\n");
    }
    for (k, v) in headers {
        text += &format!("{k}: {v}\r\n");
    }
    text += "\r\n";
    stream.write_all(text.as_bytes()).unwrap();
    let mut raw = Vec::new();
    stream.read_to_end(&mut raw).unwrap();
    let split = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("no end of headers");
    let head = String::from_utf8(raw[..split].to_vec()).unwrap();
    let status = head.split(' ').nth(1).unwrap().parse().unwrap();
    Response {
        status,
        head,
        body: raw[split + 4..].to_vec(),
    }
}

/// A WebSocket client of `/api/live` that decodes the messages from the
/// layouts documented in src/serve/mod.rs.
struct Live {
    socket: tungstenite::WebSocket<TcpStream>,
    /// The snapshot of the last colour frame received.
    last_seq: Option<u64>,
}

/// The mesh message.
struct MeshMessage {
    positions: Vec<[f32; 3]>,
    rho: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
}

/// A colour frame.
struct Frame {
    seq: u32,
    full: bool,
    ambient: [f32; 3],
    vertices: Vec<(u32, [u8; 4])>,
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

/// Ward's RGBE as Radiance decodes it.
fn decode_rgbe(c: [u8; 4]) -> [f64; 3] {
    if c[3] == 0 {
        return [0.0; 3];
    }
    let f = 2f64.powi(i32::from(c[3]) - 136);
    [0, 1, 2].map(|k| (f64::from(c[k]) + 0.5) * f)
}

enum Received {
    Text(Value),
    Binary(Vec<u8>),
}

impl Live {
    fn receive(&mut self) -> Received {
        loop {
            match self.socket.read().unwrap() {
                Message::Text(t) => return Received::Text(serde_json::from_str(&t).unwrap()),
                Message::Binary(b) => return Received::Binary(b.to_vec()),
                _ => {}
            }
        }
    }

    fn text(&mut self) -> Value {
        match self.receive() {
            Received::Text(v) => v,
            Received::Binary(_) => panic!("expected a text message"),
        }
    }

    /// The scene and mesh messages that open the feed.
    fn opening(&mut self) -> (Value, MeshMessage) {
        let scene = self.text();
        assert_eq!(scene["type"], "scene");
        let Received::Binary(m) = self.receive() else {
            panic!("expected the mesh message");
        };
        assert_eq!(&m[..4], b"RMSH");
        let v = u32_at(&m, 4) as usize;
        let t = u32_at(&m, 8) as usize;
        assert_eq!(m.len(), 12 + 24 * v + 12 * t);
        let vec3 = |at: usize| [f32_at(&m, at), f32_at(&m, at + 4), f32_at(&m, at + 8)];
        let mesh = MeshMessage {
            positions: (0..v).map(|i| vec3(12 + 12 * i)).collect(),
            rho: (0..v).map(|i| vec3(12 + 12 * v + 12 * i)).collect(),
            triangles: (0..t)
                .map(|k| {
                    let at = 12 + 24 * v + 12 * k;
                    [u32_at(&m, at), u32_at(&m, at + 4), u32_at(&m, at + 8)]
                })
                .collect(),
        };
        (scene, mesh)
    }

    /// The next status message and the colour frame that follows it when
    /// its snapshot is one this client has not had.
    fn update(&mut self) -> (Value, Option<Frame>) {
        let status = self.text();
        assert_eq!(status["type"], "status");
        let seq = status["seq"].as_u64().unwrap();
        if seq == 0 || self.last_seq == Some(seq) {
            return (status, None);
        }
        let Received::Binary(b) = self.receive() else {
            panic!("expected the colour frame of snapshot {seq}");
        };
        let frame = decode_frame(&b);
        assert_eq!(u64::from(frame.seq), seq);
        self.last_seq = Some(seq);
        (status, Some(frame))
    }
}

fn decode_frame(b: &[u8]) -> Frame {
    assert_eq!(&b[..4], b"RCOL");
    let n = u32_at(b, 8) as usize;
    let full = u32_at(b, 12) & 1 != 0;
    let ambient = [f32_at(b, 16), f32_at(b, 20), f32_at(b, 24)];
    let colour = |at: usize| -> [u8; 4] { b[at..at + 4].try_into().unwrap() };
    let vertices = if full {
        assert_eq!(b.len(), 28 + 4 * n);
        (0..n).map(|i| (i as u32, colour(28 + 4 * i))).collect()
    } else {
        assert_eq!(b.len(), 28 + 8 * n);
        (0..n)
            .map(|k| (u32_at(b, 28 + 4 * k), colour(28 + 4 * n + 4 * k)))
            .collect()
    };
    Frame {
        seq: u32_at(b, 4),
        full,
        ambient,
        vertices,
    }
}

/// Rows of the vertex CSV: position and radiosity.
fn read_csv(path: &Path) -> Vec<([f64; 3], [f64; 3])> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("x,y,z,nx,ny,nz,surface,r,g,b"));
    lines
        .map(|line| {
            let f: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
            assert_eq!(f.len(), 10);
            ([f[0], f[1], f[2]], [f[7], f[8], f[9]])
        })
        .collect()
}

/// A JSON array of three numbers.
fn vec3(value: &Value) -> [f64; 3] {
    let a = value.as_array().expect("an array");
    assert_eq!(a.len(), 3);
    [0, 1, 2].map(|k| a[k].as_f64().unwrap())
}

fn read_json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The picture decodes at the size asked for.
fn assert_png(path: &Path, width: u32, height: u32) {
    let decoder = png::Decoder::new(BufReader::new(std::fs::File::open(path).unwrap()));
    let reader = decoder.read_info().unwrap();
    assert_eq!((reader.info().width, reader.info().height), (width, height));
}

#[test]
fn prints_its_address_and_serves_the_embedded_page() {
    let served = Served::start(&LONG_SOLVE);
    assert!(served.address.ip().is_loopback());
    assert_ne!(served.address.port(), 0);

    let page = served.get("/");
    assert_eq!(page.status, 200);
    assert!(
        page.header("content-type")
            .unwrap()
            .starts_with("text/html")
    );
    let html = String::from_utf8(page.body.clone()).unwrap();
    assert!(html.contains(r#"<script type="importmap">"#));
    assert!(html.contains(r#""three": "/vendor/three/build/three.module.js""#));
    assert!(html.contains(r#"src="/serve.js""#));
    // Framing is forbidden (the stop button must not be clickjacked).
    assert_eq!(page.header("x-frame-options"), Some("DENY"));
    assert!(
        page.header("content-security-policy")
            .unwrap()
            .contains("frame-ancestors 'none'")
    );

    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("web");
    for (url, file) in [
        ("/index.html", "serve/index.html"),
        ("/serve.js", "serve/serve.js"),
        (
            "/vendor/three/build/three.module.js",
            "vendor/three/build/three.module.js",
        ),
        (
            "/vendor/three/build/three.core.js",
            "vendor/three/build/three.core.js",
        ),
        (
            "/vendor/three/examples/jsm/controls/OrbitControls.js",
            "vendor/three/examples/jsm/controls/OrbitControls.js",
        ),
    ] {
        let r = served.get(url);
        assert_eq!(r.status, 200, "{url}");
        assert_eq!(r.body, std::fs::read(root.join(file)).unwrap(), "{url}");
        if url.ends_with(".js") {
            assert!(
                r.header("content-type")
                    .unwrap()
                    .starts_with("text/javascript")
            );
        }
    }
    served.post("/api/stop");
    served.wait_finished();
}

/// No route reads a file: paths that climb, encode, or name files of the
/// repository or the system all get 404 (or 400), never content.
#[test]
fn serves_no_path_from_the_disk() {
    let served = Served::start(&LONG_SOLVE);
    for path in [
        "/../Cargo.toml",
        "/../../../../etc/passwd",
        "/vendor/../../Cargo.toml",
        "/vendor/three/../../../Cargo.toml",
        "/%2e%2e/Cargo.toml",
        "/%2e%2e%2f%2e%2e%2fetc%2fpasswd",
        "/..%2f..%2fCargo.toml",
        "//etc/passwd",
        "/Cargo.toml",
        "/src/main.rs",
        "/web/serve/index.html",
        "/serve/index.html",
        "/vendor/three/LICENSE",
        "/vendor/three/package.json",
        "/vendor/three/examples/jsm/loaders/GLTFLoader.js",
        "/api/vertex/..%2f..%2fCargo.toml",
        "/api/scene?path=/etc/passwd",
        "/index.html/../../Cargo.toml",
    ] {
        let r = served.get(path);
        assert!(matches!(r.status, 400 | 404), "{path}: {}", r.status);
        let body = String::from_utf8_lossy(&r.body);
        assert!(
            !body.contains("[package]") && !body.contains("root:") && !body.contains("fn main"),
            "{path}"
        );
    }
    // The controls take no arguments and no file; other methods are refused.
    // (Vertex queries answer 503 while the scene is loading: wait for it.)
    served.wait_for("the scene", |s| s["phase"] != "loading");
    assert_eq!(served.get("/api/stop").status, 405);
    assert_eq!(served.get("/api/vertex/abc").status, 400);
    assert_eq!(served.get("/api/vertex/-1").status, 400);
    assert_eq!(served.get("/api/vertex/4294967295").status, 404);
    served.post("/api/stop");
    served.wait_finished();
}

/// Requests naming another host (DNS rebinding) or coming from another
/// site's page are refused, and change nothing.
#[test]
fn refuses_other_hosts_and_origins() {
    let served = Served::start(&LONG_SOLVE);
    let a = served.address;
    let port = a.port();
    let r = request(a, "GET", "/", &[("Host", format!("evil.example:{port}"))]);
    assert_eq!(r.status, 403);
    assert!(!String::from_utf8_lossy(&r.body).contains("importmap"));
    let r = request(
        a,
        "GET",
        "/api/status",
        &[("Host", format!("127.0.0.1:{}", port + 1))],
    );
    assert_eq!(r.status, 403);
    assert_eq!(
        request(a, "GET", "/", &[("Host", format!("localhost:{port}"))]).status,
        200
    );

    let evil = [("Origin", "http://evil.example".to_string())];
    assert_eq!(request(a, "POST", "/api/stop", &evil).status, 403);
    assert_eq!(request(a, "POST", "/api/pause", &evil).status, 403);
    assert_eq!(request(a, "GET", "/api/vertex/0", &evil).status, 403);
    let status = served.status();
    assert_eq!(status["stop_requested"], false);
    assert_eq!(status["pause_requested"], false);
    assert_ne!(status["phase"], "paused");

    let mut handshake = format!("ws://{a}/api/live").into_client_request().unwrap();
    handshake
        .headers_mut()
        .insert("Origin", "http://evil.example".parse().unwrap());
    match tungstenite::connect(handshake) {
        Err(tungstenite::Error::Http(response)) => assert_eq!(response.status(), 403),
        other => panic!(
            "a cross-site WebSocket was accepted: {:?}",
            other.map(|_| ())
        ),
    }
    // The page's own origin passes.
    let own = [("Origin", format!("http://{a}"))];
    assert_eq!(request(a, "POST", "/api/stop", &own).status, 200);
    served.wait_finished();
}

/// The live feed: the scene, the mesh, then status and colour frames while
/// the solve runs (unshot power falling, frames carrying only what
/// changed, snapshots taken while solving a quarter second of solve time
/// apart); after Stop, the colours decoded from the frames are the
/// solver's radiosities as the vertex CSV has them, within RGBE's
/// precision, and a client connecting after the end gets the same state.
/// The solve is held before its first shot, at shot 300 (unshot power
/// below 2%) and at each of the three after: what the client is sent there
/// is the same on any machine. One shooter a round (`--round 1`), so that
/// the holds fall on those very counts (a round of several shooters goes
/// past them together).
#[test]
fn live_frames_decode_to_the_solvers_colours() {
    let mut args = LONG_SOLVE.to_vec();
    args.extend(["--pause-at", "0,300,301,302,303", "--round", "1"]);
    let served = Served::start(&args);
    let mut live = served.websocket();
    let (scene, mesh) = live.opening();
    let v = mesh.positions.len();
    assert_eq!(scene["name"], "cornell");
    assert_eq!(scene["vertices"].as_u64().unwrap() as usize, v);
    assert_eq!(
        scene["triangles"].as_u64().unwrap() as usize,
        mesh.triangles.len()
    );
    assert!(mesh.triangles.iter().flatten().all(|&i| (i as usize) < v));
    assert!(mesh.rho.iter().flatten().all(|&r| (0.0..1.0).contains(&r)));
    let eye = &scene["camera"]["eye"];
    assert!(eye.as_array().unwrap().iter().all(|x| x.is_f64()));

    let mut colours = vec![[0u8; 4]; v];
    let mut seen_full = false;
    let mut partial_frames = 0;
    // The unshot fraction of each frame's snapshot.
    let mut unshot = Vec::new();
    let mut last_seq = 0;
    // Solve time of each snapshot taken while solving, after the first
    // shot's.
    let mut snapshot_times = Vec::new();
    let mut watch = |live: &mut Live, until: u64| loop {
        let (status, frame) = live.update();
        let framed = frame.is_some();
        if let Some(frame) = frame {
            assert!(frame.seq > last_seq, "snapshots go forward");
            last_seq = frame.seq;
            if !seen_full {
                assert!(frame.full, "a client's first frame is full");
                seen_full = true;
            }
            if !frame.full {
                partial_frames += 1;
                assert!(frame.vertices.len() * 2 <= v);
                assert!(frame.vertices.windows(2).all(|w| w[0].0 < w[1].0));
            }
            for (i, c) in frame.vertices {
                colours[i as usize] = c;
            }
            if status["phase"] == "solving" && status["shots"].as_u64() > Some(1) {
                snapshot_times.push(status["elapsed_seconds"].as_f64().unwrap());
            }
            unshot.push(status["unshot_fraction"].as_f64().unwrap());
        }
        assert_ne!(
            status["phase"], "finished",
            "the solve ended before its hold"
        );
        if framed && status["phase"] == "paused" && status["shots"].as_u64() == Some(until) {
            return status;
        }
    };
    let before = watch(&mut live, 0);
    assert_eq!(before["unshot_fraction"], 1.0, "nothing shot yet");
    assert_eq!(served.post("/api/resume").status, 200);
    let mut held = vec![watch(&mut live, 300)];
    for shots in 301..=303 {
        assert_eq!(served.post("/api/resume").status, 200);
        held.push(watch(&mut live, shots));
    }
    assert!(partial_frames > 0, "one shot changes few vertices' colours");
    assert!(unshot.len() >= 5, "{unshot:?}");
    let held: Vec<f64> = held
        .iter()
        .map(|s| s["unshot_fraction"].as_f64().unwrap())
        .collect();
    assert!(held[0] < 0.02, "{held:?}");
    assert!(held.windows(2).all(|w| w[1] < w[0]), "{held:?}");
    // Throttled: the snapshots taken while solving are at least 250 ms of
    // solving apart (the server's own clock: how many there are depends on
    // the machine's speed, their spacing does not).
    assert!(
        snapshot_times
            .windows(2)
            .all(|w| w[1] - w[0] >= 0.25 - 1e-9),
        "{snapshot_times:?}"
    );

    assert_eq!(served.post("/api/stop").status, 200);
    let mut final_ambient = [0.0; 3];
    loop {
        let (status, frame) = live.update();
        if let Some(frame) = frame {
            for (i, c) in frame.vertices {
                colours[i as usize] = c;
            }
            final_ambient = frame.ambient;
        }
        if status["phase"] == "finished" {
            assert_eq!(status["stop_reason"], "stopped");
            assert_eq!(status["written"].as_array().unwrap().len(), 3);
            break;
        }
    }

    let csv = read_csv(&served.path("out.csv"));
    assert_eq!(csv.len(), v);
    for (i, (position, b)) in csv.iter().enumerate() {
        for (sent, written) in mesh.positions[i].iter().zip(position) {
            assert_abs_diff_eq!(f64::from(*sent), written, epsilon = 1e-5);
        }
        let decoded = decode_rgbe(colours[i]);
        let tolerance = b.iter().copied().fold(0.0, f64::max) / 128.0 + 1e-30;
        for k in 0..3 {
            assert!(
                abs_diff_eq!(decoded[k], b[k], epsilon = tolerance),
                "vertex {i}: decoded {decoded:?}, solver {b:?}"
            );
        }
    }
    let stats = read_json(&served.path("out.json"));
    assert_eq!(stats["stop_reason"], "stopped");
    assert_eq!(stats["shots"], 303, "stopped where it was held");
    assert_eq!(
        stats["unshot_fraction"].as_f64().unwrap(),
        *unshot.last().unwrap()
    );
    assert_png(&served.path("out.png"), 64, 48);

    // The picker reports the solver's value to full precision.
    for i in [0usize, v / 2, v - 1] {
        let r = served.get(&format!("/api/vertex/{i}"));
        assert_eq!(r.status, 200);
        let vertex: Value = serde_json::from_slice(&r.body).unwrap();
        let b = vec3(&vertex["radiosity"]);
        for k in 0..3 {
            // serde_json parses floats to within an ulp or so.
            assert!(
                abs_diff_eq!(b[k], csv[i].1[k], epsilon = 1e-14 * b[k]),
                "vertex {i}: {b:?}"
            );
        }
        let ambient = vec3(&vertex["ambient"]);
        for k in 0..3 {
            assert_abs_diff_eq!(
                ambient[k],
                f64::from(final_ambient[k]),
                epsilon = 1e-6 * ambient[k].max(1e-9)
            );
            let rho = f64::from(mesh.rho[i][k]);
            let display = vertex["display"][k].as_f64().unwrap();
            assert_abs_diff_eq!(
                display,
                (b[k] + rho * ambient[k]),
                epsilon = 1e-6 * display.max(1e-9)
            );
        }
    }

    // A second browser after the end gets the final state in one frame.
    let mut late = served.websocket();
    let (_, late_mesh) = late.opening();
    assert_eq!(late_mesh.triangles, mesh.triangles);
    let (status, frame) = late.update();
    assert_eq!(status["phase"], "finished");
    let frame = frame.expect("the current state");
    assert!(frame.full);
    assert_eq!(
        frame.vertices.iter().map(|(_, c)| *c).collect::<Vec<_>>(),
        colours
    );
    drop(late);
    drop(live);

    served.interrupt();
    let mut served = served;
    let (status, _) = served.exit();
    assert!(status.success(), "{status}");
}

/// Pause holds the solve until resume; the page's pause and a hold of
/// `--pause-at` are the same pause; stop while paused ends the solve with
/// no shot after the pause. (Held at shot 3, and at shot 1,000 so that the
/// solve is still there, paused, however fast the machine.)
#[test]
fn pause_holds_the_solve_until_resume() {
    let mut args = LONG_SOLVE.to_vec();
    args.extend(["--pause-at", "3,1000"]);
    let served = Served::start(&args);
    let held = served.wait_for("the hold", |s| s["phase"] == "paused");
    assert_eq!(held["shots"], 3);
    assert_eq!(held["pause_requested"], false);
    // Pressing pause while paused changes nothing.
    assert_eq!(served.post("/api/pause").status, 200);
    let still = served.status();
    assert_eq!(still["phase"], "paused");
    assert_eq!(still["pause_requested"], false);
    assert_eq!(still["shots"], 3);
    assert_eq!(still["seq"], held["seq"]);
    served.post("/api/resume");
    served.wait_for("shots after resume", |s| s["shots"].as_u64() > Some(3));
    // The page's pause, taken after the current shot (or the hold at 1,000
    // first).
    let r = served.post("/api/pause");
    assert_eq!(r.status, 200);
    let paused = served.wait_for("the pause", |s| s["phase"] == "paused");
    assert_eq!(paused["pause_requested"], false);
    let shots = paused["shots"].as_u64().unwrap();
    assert!((4..=1000).contains(&shots), "{paused}");
    served.post("/api/stop");
    let end = served.wait_finished();
    assert_eq!(end["stop_reason"], "stopped");
    assert_eq!(end["shots"], shots, "no shot after the pause");
    let stats = read_json(&served.path("out.json"));
    assert_eq!(stats["shots"], shots);
    assert_eq!(stats["stop_reason"], "stopped");
}

/// Ctrl-C during the solve stops it, writes every output from the state
/// reached, closes the live connections and exits with status 0. (Held at
/// shot 3 by `--pause-at`, so the solve is still there whatever the
/// machine's speed.)
#[test]
fn ctrl_c_during_the_solve_writes_the_outputs_and_exits() {
    let mut args = LONG_SOLVE.to_vec();
    args.extend(["--pause-at", "3"]);
    let served = Served::start(&args);
    let mut live = served.websocket();
    let (scene, _) = live.opening();
    served.wait_for("the hold", |s| s["phase"] == "paused");
    let out = served.path("out.csv");
    let stats = served.path("out.json");
    let picture = served.path("out.png");
    served.interrupt();
    // The page is told, then the connection closes.
    let closed = loop {
        match live.socket.read() {
            Ok(Message::Close(_)) | Err(_) => break true,
            Ok(_) => {}
        }
    };
    assert!(closed);
    let mut served = served;
    let (status, stderr) = served.exit();
    assert!(status.success(), "{status}: {stderr}");
    let json = read_json(&stats);
    assert_eq!(json["stop_reason"], "stopped");
    assert_eq!(json["shots"], 3);
    assert_eq!(
        read_csv(&out).len() as u64,
        scene["vertices"].as_u64().unwrap()
    );
    assert_png(&picture, 64, 48);
    // Nothing else (no temporary file) is left.
    assert_eq!(std::fs::read_dir(served.dir.path()).unwrap().count(), 3);
}

/// After the solve ends the final state is still served until Ctrl-C,
/// which then exits at once.
#[test]
fn serves_the_final_state_until_ctrl_c() {
    let served = Served::start(&["--max-shots", "3", "--threads", "1"]);
    let end = served.wait_finished();
    assert_eq!(end["stop_reason"], "max-shots reached");
    assert_eq!(end["shots"], 3);
    assert_eq!(read_json(&served.path("out.json"))["shots"], 3);
    let mut live = served.websocket();
    live.opening();
    let (status, frame) = live.update();
    assert_eq!(status["shots"], 3);
    assert!(frame.unwrap().full);
    assert_eq!(served.get("/").status, 200);
    served.interrupt();
    let mut served = served;
    let (status, _) = served.exit();
    assert!(status.success());
}

/// The PNG's size and RGB bytes.
fn decode_png(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buffer).unwrap();
    buffer.truncate(info.buffer_size());
    (info.width, info.height, buffer)
}

/// Once the solve has ended, the server draws it with the final pass at
/// the size the page said it draws at, from the scene's view: the very
/// picture `radiosity render` draws of the same solve at that size. With
/// `--final-gather off` there is none.
#[test]
fn the_ended_solve_is_drawn_with_the_final_pass() {
    let served = Served::start(&["--pause-at", "0", "--max-shots", "40", "--threads", "1"]);
    served.wait_for("the hold", |s| s["phase"] == "paused");
    assert_eq!(served.get("/api/frame.png").status, 404);
    assert_eq!(served.post("/api/view/80/60").status, 204);
    served.post("/api/resume");
    let end = served.wait_for("the final picture", |s| !s["frame"].is_null());
    assert_eq!(end["frame"], serde_json::json!([80, 60]));
    let r = served.get("/api/frame.png");
    assert_eq!(r.status, 200);
    assert_eq!(r.header("content-type"), Some("image/png"));
    let (width, height, pixels) = decode_png(&r.body);
    assert_eq!((width, height), (80, 60));
    let picture = served.path("cli.png");
    let out = Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .env("RADIOSITY_DEVICE", "cpu")
        .args([
            "render",
            "cornell",
            "-q",
            "--max-shots",
            "40",
            "--threads",
            "1",
        ])
        .args(["--width", "80", "--height", "60", "--output"])
        .arg(&picture)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (_, _, ours) = decode_png(&std::fs::read(&picture).unwrap());
    assert_eq!(pixels, ours, "the server's picture is the command's");

    let off = Served::start(&[
        "--max-shots",
        "3",
        "--threads",
        "1",
        "--final-gather",
        "off",
    ]);
    let end = off.wait_finished();
    assert!(end["frame"].is_null(), "{end}");
    assert_eq!(off.get("/api/frame.png").status, 404);
}

/// The listening socket is bound to 127.0.0.1 unless `--host` says
/// otherwise (read from the kernel's socket table, sending nothing
/// anywhere but loopback).
#[cfg(target_os = "linux")]
#[test]
fn binds_loopback_unless_told() {
    /// Local addresses of the listening IPv4 sockets on `port`, one per
    /// socket: the kernel's table is read in pieces, so a socket can be
    /// listed twice when other sockets (the other tests') open or close
    /// meanwhile; its inode (the tenth field) tells the copies apart.
    fn listening(port: u16) -> Vec<String> {
        let table = std::fs::read_to_string("/proc/net/tcp").unwrap();
        let mut sockets: Vec<(String, String)> = table
            .lines()
            .skip(1)
            .filter_map(|line| {
                let fields: Vec<&str> = line.split_whitespace().collect();
                let (address, p) = fields[1].split_once(':')?;
                let inode = fields.get(9)?;
                (fields[3] == "0A" && u16::from_str_radix(p, 16).ok()? == port)
                    .then(|| (inode.to_string(), address.to_string()))
            })
            .collect();
        sockets.sort();
        sockets.dedup();
        sockets.into_iter().map(|(_, address)| address).collect()
    }
    let served = Served::start(&LONG_SOLVE);
    assert_eq!(served.address.ip().to_string(), "127.0.0.1");
    // 127.0.0.1 in the kernel's (little-endian) hex.
    assert_eq!(listening(served.address.port()), ["0100007F"]);
    served.post("/api/stop");
    served.wait_finished();
    drop(served);

    let dir = tempfile::tempdir().unwrap();
    let mut command = Command::new(env!("CARGO_BIN_EXE_radiosity"));
    command.env("RADIOSITY_DEVICE", "cpu");
    command.args([
        "serve",
        "cornell",
        "--host",
        "0.0.0.0",
        "--port",
        "0",
        "--max-shots",
        "1",
        "--threads",
        "1",
        "--width",
        "16",
        "--height",
        "12",
        "--output",
    ]);
    command.arg(dir.path().join("all.png"));
    let all = Served::spawn(command, dir);
    assert!(all.address.ip().is_unspecified());
    assert_eq!(listening(all.address.port()), ["00000000"]);
    let r = request(
        SocketAddr::from(([127, 0, 0, 1], all.address.port())),
        "GET",
        "/api/status",
        &[],
    );
    assert_eq!(r.status, 200);
}

#[test]
fn bad_input_fails_with_one_clear_error() {
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_radiosity"))
            .env("RADIOSITY_DEVICE", "cpu")
            .arg("serve")
            .args(args)
            .output()
            .unwrap()
    };
    let missing = run(&["no-such-scene.obj", "--port", "0"]);
    assert!(!missing.status.success());
    let stderr = String::from_utf8_lossy(&missing.stderr);
    assert!(stderr.contains("no-such-scene.obj"), "{stderr}");
    assert!(!stderr.contains("panicked"));

    let host = run(&["cornell", "--host", "example.com"]);
    assert!(!host.status.success());
    assert!(String::from_utf8_lossy(&host.stderr).contains("--host"));

    let port = run(&["cornell", "--port", "70000"]);
    assert!(!port.status.success());
    assert!(String::from_utf8_lossy(&port.stderr).contains("--port"));

    // A port in use: one error naming the address, before any solving.
    let busy = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let taken = busy.local_addr().unwrap().port().to_string();
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("x.png");
    let r = run(&[
        "cornell",
        "--port",
        &taken,
        "--output",
        output.to_str().unwrap(),
    ]);
    assert!(!r.status.success());
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(stderr.contains(&format!("127.0.0.1:{taken}")), "{stderr}");
    assert!(!output.exists());

    // Output options are checked before the server starts.
    let r = run(&[
        "cornell",
        "--port",
        "0",
        "--output",
        "/no/such/folder/x.png",
    ]);
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stdout).is_empty());
}
