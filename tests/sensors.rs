//! Values at sensor points through the command (`--sensors`): the CSV has
//! one row per point in input order, holding the vertices' values at
//! vertex points; every malformed points file and bad flag is refused with
//! its file, line and problem, before solving and without output. The
//! library's sensor tests (closed forms, placement, threads) are in
//! crates/radiosity/tests/sensors.rs.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use approx::{abs_diff_eq, assert_abs_diff_eq};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .env("RADIOSITY_DEVICE", "cpu")
        .args(args)
        .output()
        .expect("the binary runs")
}

const BOX_OBJ: &str = "mtllib box.mtl\n\
    v 0 0 0\nv 2 0 0\nv 2 0 1.8\nv 0 0 1.8\n\
    v 0 1.5 0\nv 2 1.5 0\nv 2 1.5 1.8\nv 0 1.5 1.8\n\
    v 0.7 1.4 0.6\nv 1.3 1.4 0.6\nv 1.3 1.4 1.2\nv 0.7 1.4 1.2\n\
    usemtl white\nf 1 4 3 2\nf 5 6 7 8\nf 1 5 8 4\nf 2 3 7 6\nf 1 2 6 5\nf 4 8 7 3\n\
    usemtl light\nf 9 10 11 12\n";
const BOX_MTL: &str = "newmtl white\nKd 0.7 0.6 0.5\nnewmtl light\nKe 20 18 15\n";

struct Case {
    dir: tempfile::TempDir,
}

impl Case {
    fn new() -> Case {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("box.obj"), BOX_OBJ).unwrap();
        std::fs::write(dir.path().join("box.mtl"), BOX_MTL).unwrap();
        Case { dir }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    fn arg(&self, name: &str) -> String {
        self.path(name).to_string_lossy().into_owned()
    }

    fn render(&self, extra: &[&str]) -> Output {
        let mut args = vec![
            "render".to_string(),
            self.arg("box.obj"),
            "--output".into(),
            self.arg("out.png"),
            "--width".into(),
            "16".into(),
            "--height".into(),
            "12".into(),
            "--patch-size".into(),
            "0.6".into(),
            "--element-size".into(),
            "0.3".into(),
            "--quiet".into(),
        ];
        args.extend(extra.iter().map(|s| s.to_string()));
        run(&args.iter().map(String::as_str).collect::<Vec<_>>())
    }

    fn files(&self) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(self.dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }
}

fn csv_rows(path: &Path) -> (String, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_string();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    (header, rows)
}

/// Through the command line, with patch shooting (exact; see
/// `sensors_at_vertices_get_the_vertex_values` in
/// crates/radiosity/tests/sensors.rs): sensors at every vertex, given last
/// first, get the vertices' values in the order given, and adding them
/// changes no vertex's value.
#[test]
fn the_cli_writes_vertex_values_at_vertex_points_in_input_order() {
    let case = Case::new();
    let out = case.render(&["--preset", "wong-tsang93", "--vertices", &case.arg("v.csv")]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (_, vertices) = csv_rows(&case.path("v.csv"));
    // Every vertex as a sensor, in reverse order, with a comment and a
    // normal that is not unit length.
    let mut points = String::from("# every vertex, last first\n");
    for v in vertices.iter().rev() {
        points.push_str(&format!(
            "{} {} {} {} {} {}\n",
            v[0],
            v[1],
            v[2],
            3.0 * v[3],
            3.0 * v[4],
            3.0 * v[5]
        ));
    }
    std::fs::write(case.path("p.txt"), points).unwrap();
    let out = case.render(&[
        "--preset",
        "wong-tsang93",
        "--vertices",
        &case.arg("v2.csv"),
        "--sensors",
        &case.arg("p.txt"),
        "--sensors-out",
        &case.arg("s.csv"),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (header, sensors) = csv_rows(&case.path("s.csv"));
    assert_eq!(header, "x,y,z,nx,ny,nz,er,eg,eb,br,bg,bb,lux");
    assert_eq!(sensors.len(), vertices.len());
    assert_eq!(csv_rows(&case.path("v2.csv")).1, vertices);
    for (s, v) in sensors.iter().zip(vertices.iter().rev()) {
        assert_eq!(&s[0..3], &v[0..3]);
        // Normals as given, normalised: to round-off.
        for c in 3..6 {
            assert!(abs_diff_eq!(s[c], v[c], epsilon = 1e-15), "{s:?} vs {v:?}");
        }
        for c in 0..3 {
            let (b, vb) = (s[9 + c], v[7 + c]);
            assert!(
                abs_diff_eq!(b, vb, epsilon = 1e-12 * vb.abs().max(1e-300)),
                "{s:?} vs {v:?}"
            );
        }
        // Light surfaces (Kd 0) have B = Ke; white ones B = Kd E.
        let lux = 179.0 * (0.265 * s[6] + 0.670 * s[7] + 0.065 * s[8]);
        assert_abs_diff_eq!(s[12], lux, epsilon = 1e-12 * lux.max(1e-300));
    }
}

/// Runs with a points file and checks the one error line, the exit status
/// and that nothing was written.
fn assert_refused(points: &[u8], extra: &[&str], expected: &str) {
    let case = Case::new();
    std::fs::write(case.path("p.txt"), points).unwrap();
    let mut args = vec![
        "--sensors".to_string(),
        case.arg("p.txt"),
        "--sensors-out".into(),
        case.arg("s.csv"),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    let out = case.render(&args.iter().map(String::as_str).collect::<Vec<_>>());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    let expected = format!("error: {}", expected.replace("{dir}", &case.arg("")));
    assert_eq!(stderr.trim_end(), expected.trim_end_matches('/'));
    assert_eq!(case.files(), ["box.mtl", "box.obj", "p.txt"]);
}

#[test]
fn the_cli_refuses_bad_points_files_with_their_line() {
    assert_refused(
        b"1 0 1 0 1 0\n1 0 1 0 1\n",
        &[],
        "{dir}p.txt:2: a point needs 6 numbers, x y z nx ny nz; this line has 5",
    );
    assert_refused(
        b"1 0 1 0 1 0 A1\n",
        &[],
        "{dir}p.txt:1: 'A1' is not a number",
    );
    assert_refused(
        b"# desks\n1 0.8 1 0 1 0\n",
        &[],
        "{dir}p.txt:2: the point (1, 0.8, 1) lies on no surface facing along its normal \
         (0.000, 1.000, 0.000): the nearest surface facing that way is 80.0 cm away, and a point \
         must lie within 0.31 mm of its surface",
    );
    assert_refused(
        b"",
        &[],
        "{dir}p.txt: no points in the file: each line holds x y z nx ny nz",
    );
    assert_refused(
        b"1 0 1 0 1 0\n1 0 1 0 1 0\n",
        &["--max-sensors", "1"],
        "{dir}p.txt:2: more than 1 points (raise the limit with --max-sensors)",
    )
}

#[test]
fn the_cli_checks_sensor_flags_and_outputs_before_solving() {
    let case = Case::new();
    std::fs::write(case.path("p.txt"), "1 0 1 0 1 0\n").unwrap();
    let alone = case.render(&["--sensors", &case.arg("p.txt")]);
    assert_eq!(alone.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&alone.stderr).contains("--sensors-out"));
    let out = case.render(&[
        "--sensors",
        &case.arg("p.txt"),
        "--sensors-out",
        &case.arg("missing/s.csv"),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr.contains("missing/s.csv: cannot write: folder") && stderr.contains("does not exist"),
        "{stderr}"
    );
    let wrong = case.render(&[
        "--sensors",
        &case.arg("p.txt"),
        "--sensors-out",
        &case.arg("s.txt"),
    ]);
    assert!(String::from_utf8_lossy(&wrong.stderr).contains("--sensors-out "));
    let missing = case.render(&[
        "--sensors",
        &case.arg("nothere.txt"),
        "--sensors-out",
        &case.arg("s.csv"),
    ]);
    assert!(String::from_utf8_lossy(&missing.stderr).contains("nothere.txt: No such file"));
    assert_eq!(case.files(), ["box.mtl", "box.obj", "p.txt"]);
}
