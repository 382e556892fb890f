//! IES LM-63 photometric files (LM-63-1986, -1991, -1995 and -2002), the
//! way luminaire makers publish their lights' intensity distributions:
//! keyword lines, `TILT=NONE`, then numbers (lamp count, lumens per lamp,
//! candela multiplier, the angle counts, photometric type and units,
//! luminous opening, ballast factor, a ballast-lamp factor or future use,
//! input watts), the vertical and horizontal angles in degrees and one
//! candela value per pair, horizontal angle by horizontal angle.
//!
//! Only type C photometry (the type of nearly every interior luminaire)
//! is read, with any of the standard's horizontal symmetries: a single
//! horizontal angle (the same in every direction around the axis), 0-90
//! (quadrants), 0-180 (bilateral about the 0-180 plane), 90-270 (bilateral
//! about the 90-270 plane) or 0-360. Vertical angles run from the nadir
//! (0) towards the zenith (180) and may cover 0-90, 90-180 or 0-180; there
//! is no light outside them. Between tabulated angles the candela values
//! are interpolated bilinearly, as Radiance's `ies2rad` data files are.
//!
//! Angles are those of the luminaire: `gamma` from its nadir, `C`
//! counter-clockwise about its upward axis seen from above, from its C0
//! direction. Candela values are scaled by the file's candela multiplier,
//! ballast factor and ballast-lamp factor.
//!
//! Every problem is an error naming the line and what is wrong; nothing in
//! a file can make the parser panic, allocate without bound or loop.

use std::f64::consts::PI;

/// Most angles of either kind a file may list.
pub const MAX_ANGLES: usize = 10_000;

/// Most candela values a file may hold.
pub const MAX_VALUES: usize = 1_000_000;

/// A luminaire's intensity distribution, in candela.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    /// Vertical angles, degrees from the nadir, increasing.
    vertical: Vec<f64>,
    /// Horizontal angles, degrees, increasing.
    horizontal: Vec<f64>,
    /// `candela[h * vertical.len() + v]`, scaled.
    candela: Vec<f64>,
    /// The intensity integrated over the sphere, lumens.
    flux: f64,
}

/// Why an IES file cannot be read: the line, and what is wrong.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("line {line}: {message}")]
pub struct IesError {
    /// 1-based line of the problem.
    pub line: usize,
    /// What is wrong, in words a user can act on.
    pub message: String,
}

fn error(line: usize, message: impl Into<String>) -> IesError {
    IesError {
        line,
        message: message.into(),
    }
}

/// The numbers after `TILT=NONE`, each with its line.
struct Numbers<'a> {
    tokens: Vec<(usize, &'a str)>,
    next: usize,
    last_line: usize,
}

impl Numbers<'_> {
    fn take(&mut self, what: &str) -> Result<f64, IesError> {
        let Some(&(line, token)) = self.tokens.get(self.next) else {
            return Err(error(
                self.last_line,
                format!("the file ends before {what}"),
            ));
        };
        self.next += 1;
        // Some exporters separate numbers with commas as well as spaces.
        let value: f64 = token
            .trim_matches(',')
            .parse()
            .map_err(|_| error(line, format!("'{token}' is not a number ({what})")))?;
        if !value.is_finite() {
            return Err(error(
                line,
                format!("{what} is {token}, not a finite number"),
            ));
        }
        Ok(value)
    }

    fn line(&self) -> usize {
        self.tokens
            .get(self.next.saturating_sub(1))
            .map_or(self.last_line, |t| t.0)
    }

    fn count(&mut self, what: &str, max: usize) -> Result<usize, IesError> {
        let value = self.take(what)?;
        if value.fract() != 0.0 || value < 1.0 || value > max as f64 {
            return Err(error(
                self.line(),
                format!("{what} is {value}; it must be a whole number from 1 to {max}"),
            ));
        }
        Ok(value as usize)
    }
}

/// The lines of a text, ending in LF, CR LF or CR.
struct Lines<'a> {
    text: &'a str,
    at: usize,
}

impl<'a> Iterator for Lines<'a> {
    type Item = &'a str;

    fn next(&mut self) -> Option<&'a str> {
        if self.at > self.text.len() {
            return None;
        }
        let rest = &self.text[self.at..];
        match rest.find(['\r', '\n']) {
            Some(end) => {
                let crlf = rest[end..].starts_with("\r\n");
                self.at += end + if crlf { 2 } else { 1 };
                Some(&rest[..end])
            }
            None => {
                self.at = self.text.len() + 1;
                Some(rest)
            }
        }
    }
}

/// Parses an IES LM-63 file's bytes.
pub fn parse(bytes: &[u8]) -> Result<Profile, IesError> {
    // Files come in ASCII, Latin-1 (degree signs in keywords) or UTF-8:
    // keywords are only skipped, so each byte is taken as a character.
    let text: String = bytes.iter().map(|&b| char::from(b)).collect();
    // Lines end in LF, CR LF or CR alone (old Mac files).
    let mut lines = Lines { text: &text, at: 0 }.enumerate();
    let mut tilt_line = None;
    for (i, line) in lines.by_ref() {
        let trimmed = line.trim();
        if let Some(rest) = trimmed.strip_prefix("TILT=") {
            let tilt = rest.trim();
            if tilt != "NONE" {
                return Err(error(
                    i + 1,
                    format!(
                        "TILT={tilt}: only TILT=NONE is supported (lamp-tilt tables are not \
                         read)"
                    ),
                ));
            }
            tilt_line = Some(i + 1);
            break;
        }
    }
    let Some(tilt_line) = tilt_line else {
        return Err(error(
            Lines { text: &text, at: 0 }.count(),
            "no TILT= line: this is not an IES LM-63 photometric file",
        ));
    };
    let mut tokens = Vec::new();
    for (i, line) in lines {
        for token in line.split(|c: char| c.is_whitespace() || c == ',') {
            if !token.is_empty() {
                if tokens.len() >= MAX_VALUES + 2 * MAX_ANGLES + 13 {
                    return Err(error(i + 1, "too many numbers for a photometric file"));
                }
                tokens.push((i + 1, token));
            }
        }
    }
    let last_line = tokens.last().map_or(tilt_line, |t| t.0);
    let mut n = Numbers {
        tokens,
        next: 0,
        last_line,
    };
    let _lamps = n.take("the number of lamps")?;
    let _lumens = n.take("the lumens per lamp")?;
    let multiplier = n.take("the candela multiplier")?;
    let vertical_count = n.count("the number of vertical angles", MAX_ANGLES)?;
    let horizontal_count = n.count("the number of horizontal angles", MAX_ANGLES)?;
    let kind = n.take("the photometric type")?;
    let kind_line = n.line();
    let _units = n.take("the units type")?;
    for what in [
        "the luminous width",
        "the luminous length",
        "the luminous height",
    ] {
        n.take(what)?;
    }
    let ballast = n.take("the ballast factor")?;
    let ballast_lamp = n.take("the ballast-lamp photometric factor")?;
    let _watts = n.take("the input watts")?;
    match kind {
        1.0 => {}
        2.0 | 3.0 => {
            return Err(error(
                kind_line,
                format!(
                    "photometric type {} (type {}): only type C (1) is supported",
                    kind,
                    if kind == 2.0 { "B" } else { "A" }
                ),
            ));
        }
        _ => {
            return Err(error(
                kind_line,
                format!("photometric type {kind}: it must be 1 (C), 2 (B) or 3 (A)"),
            ));
        }
    }
    if vertical_count * horizontal_count > MAX_VALUES {
        return Err(error(
            kind_line,
            format!("{vertical_count} x {horizontal_count} candela values: more than {MAX_VALUES}"),
        ));
    }
    let scale = multiplier * ballast * ballast_lamp;
    if !(scale.is_finite() && scale >= 0.0) {
        return Err(error(
            kind_line,
            format!(
                "the candela multiplier {multiplier} x ballast factor {ballast} x ballast-lamp \
                 factor {ballast_lamp} is not a finite number at least 0"
            ),
        ));
    }
    let vertical = angles(&mut n, vertical_count, "vertical")?;
    let (v0, v1) = (vertical[0], vertical[vertical_count - 1]);
    let vertical_ok = (v0 == 0.0 && (v1 == 90.0 || v1 == 180.0 || vertical_count == 1))
        || (v0 == 90.0 && v1 == 180.0);
    if !vertical_ok {
        return Err(error(
            n.line(),
            format!(
                "vertical angles run from {v0} to {v1} degrees; type C files cover 0-90, 0-180 \
                 or 90-180"
            ),
        ));
    }
    let horizontal = angles(&mut n, horizontal_count, "horizontal")?;
    let (h0, h1) = (horizontal[0], horizontal[horizontal_count - 1]);
    let horizontal_ok = matches!(
        (h0, h1),
        (0.0, 0.0) | (0.0, 90.0) | (0.0, 180.0) | (0.0, 360.0) | (90.0, 270.0)
    );
    if !horizontal_ok {
        return Err(error(
            n.line(),
            format!(
                "horizontal angles run from {h0} to {h1} degrees; type C files cover 0 (one \
                 angle), 0-90, 0-180, 90-270 or 0-360"
            ),
        ));
    }
    let mut candela = Vec::with_capacity(vertical_count * horizontal_count);
    for _ in 0..vertical_count * horizontal_count {
        let value = n.take("a candela value")?;
        if value < 0.0 {
            return Err(error(
                n.line(),
                format!("candela value {value} is negative"),
            ));
        }
        candela.push(value * scale);
    }
    if let Some(&(line, token)) = n.tokens.get(n.next) {
        return Err(error(
            line,
            format!(
                "'{token}' after the last of the {} candela values",
                vertical_count * horizontal_count
            ),
        ));
    }
    let mut profile = Profile {
        vertical,
        horizontal,
        candela,
        flux: 0.0,
    };
    profile.flux = profile.integrate();
    Ok(profile)
}

/// `count` angles, increasing.
fn angles(n: &mut Numbers<'_>, count: usize, what: &str) -> Result<Vec<f64>, IesError> {
    let mut out: Vec<f64> = Vec::with_capacity(count);
    for _ in 0..count {
        let a = n.take(&format!("the {what} angles"))?;
        if !(0.0..=360.0).contains(&a) {
            return Err(error(
                n.line(),
                format!("{what} angle {a} is outside 0-360 degrees"),
            ));
        }
        if let Some(&previous) = out.last()
            && a <= previous
        {
            return Err(error(
                n.line(),
                format!("{what} angles must increase: {a} after {previous}"),
            ));
        }
        out.push(a);
    }
    Ok(out)
}

/// Linear interpolation in a sorted table: the index below `x` and the
/// weight of the one above; `None` outside it.
fn locate(table: &[f64], x: f64) -> Option<(usize, f64)> {
    let last = table.len() - 1;
    if x < table[0] || x > table[last] {
        return None;
    }
    if last == 0 {
        return Some((0, 0.0));
    }
    let i = table.partition_point(|&t| t <= x).clamp(1, last) - 1;
    let span = table[i + 1] - table[i];
    Some((i, ((x - table[i]) / span).clamp(0.0, 1.0)))
}

impl Profile {
    /// Candela at `gamma` degrees from the nadir and horizontal angle `c`
    /// degrees (any value: folded by the file's symmetry).
    #[must_use]
    pub fn candela(&self, gamma: f64, c: f64) -> f64 {
        let Some((v, tv)) = locate(&self.vertical, gamma) else {
            return 0.0;
        };
        let last = *self.horizontal.last().expect("at least one angle");
        let mut c = c.rem_euclid(360.0);
        let first = self.horizontal[0];
        if first == 90.0 {
            // Symmetric about the 90-270 plane.
            if c < 90.0 {
                c = 180.0 - c;
            } else if c > 270.0 {
                c = 540.0 - c;
            }
        } else if last <= 180.0 && c > 180.0 {
            c = 360.0 - c;
        }
        if last == 90.0 && c > 90.0 {
            c = 180.0 - c;
        }
        let nv = self.vertical.len();
        let at = |h: usize, v: usize| self.candela[h * nv + v];
        let along = |h: usize| {
            if tv == 0.0 {
                at(h, v)
            } else {
                at(h, v) * (1.0 - tv) + at(h, v + 1) * tv
            }
        };
        if self.horizontal.len() == 1 {
            return along(0);
        }
        let (h, th) = locate(&self.horizontal, c.clamp(first, last)).unwrap_or((0, 0.0));
        if th == 0.0 {
            along(h)
        } else {
            along(h) * (1.0 - th) + along(h + 1) * th
        }
    }

    /// Luminous flux: the candela integrated over the sphere, lumens.
    #[must_use]
    pub fn flux(&self) -> f64 {
        self.flux
    }

    /// The largest tabulated candela value.
    #[must_use]
    pub fn peak(&self) -> f64 {
        self.candela.iter().copied().fold(0.0, f64::max)
    }

    /// The candela integrated over the sphere: Gauss-Legendre (4 points)
    /// on every interval between tabulated vertical angles, where the
    /// interpolated candela times `sin(gamma)` is smooth, so a beam a
    /// degree wide integrates as well as a wide one; around the axis the
    /// interpolation is linear between tabulated horizontal angles, so the
    /// trapezoid rule over them is exact, and the symmetries repeat the
    /// tabulated range around the circle. At most 4 x the candela values
    /// evaluations, each a blend of two table entries.
    fn integrate(&self) -> f64 {
        const NODES: [(f64, f64); 4] = [
            (-0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
            (-0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
            (0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
            (0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
        ];
        let nv = self.vertical.len();
        let h = &self.horizontal;
        let span = h[h.len() - 1] - h[0];
        let mut sum = 0.0;
        for i in 0..nv.saturating_sub(1) {
            let (a, b) = (
                self.vertical[i].to_radians(),
                self.vertical[i + 1].to_radians(),
            );
            let half = 0.5 * (b - a);
            for (x, w) in NODES {
                let t = 0.5 * (1.0 + x);
                let gamma = a + (b - a) * t;
                let at = |k: usize| {
                    self.candela[k * nv + i] * (1.0 - t) + self.candela[k * nv + i + 1] * t
                };
                // The mean over the circle: over the tabulated range, which
                // the symmetry repeats.
                let ring = if h.len() == 1 {
                    at(0)
                } else {
                    (0..h.len() - 1)
                        .map(|k| 0.5 * (at(k) + at(k + 1)) * (h[k + 1] - h[k]))
                        .sum::<f64>()
                        / span
                };
                sum += w * half * ring * gamma.sin();
            }
        }
        2.0 * PI * sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    const ISOTROPIC: &str = "IESNA:LM-63-2002\n[TEST] flat\n[MANUFAC] none\nTILT=NONE\n\
        1 1000 1 3 1 1 2 0 0 0\n1 1 50\n0 90 180\n0\n100 100 100\n";

    #[test]
    fn an_isotropic_file_is_a_point_light() {
        let p = parse(ISOTROPIC.as_bytes()).unwrap();
        for (g, c) in [(0.0, 0.0), (37.0, 200.0), (180.0, 10.0)] {
            assert_relative_eq!(p.candela(g, c), 100.0);
        }
        assert_relative_eq!(p.flux(), 400.0 * PI, max_relative = 1e-6);
    }

    #[test]
    fn line_ends_may_be_lf_crlf_or_cr() {
        for end in ["\n", "\r\n", "\r"] {
            let file = ISOTROPIC.replace('\n', end);
            let p = parse(file.as_bytes()).unwrap();
            assert_relative_eq!(p.candela(10.0, 0.0), 100.0);
        }
        let e = parse(b"TILT=NONE\r1 -1 1 x").unwrap_err();
        assert_eq!(e.line, 2, "{e}");
    }

    #[test]
    fn downlight_interpolates_and_is_dark_above() {
        let file = "TILT=NONE\n1 -1 2 3 1 1 2 0.1 0.1 0\n1.0 1.0 20\n0 45 90\n0\n\
                    100 50 0\n";
        let p = parse(file.as_bytes()).unwrap();
        // Multiplier 2.
        assert_relative_eq!(p.candela(0.0, 0.0), 200.0);
        assert_relative_eq!(p.candela(22.5, 123.0), 150.0);
        assert_relative_eq!(p.candela(67.5, 0.0), 50.0);
        assert_eq!(p.candela(120.0, 0.0), 0.0);
        // Flux: 2 pi int I(g) sin g dg, I linear in g on [0, 90].
        let exact = {
            let n = 200_000;
            (0..n)
                .map(|i| {
                    let g = (i as f64 + 0.5) * 90.0 / n as f64;
                    let i_g = if g <= 45.0 {
                        200.0 - 100.0 * g / 45.0
                    } else {
                        100.0 - 100.0 * (g - 45.0) / 45.0
                    };
                    i_g * g.to_radians().sin() * (90.0 / n as f64).to_radians()
                })
                .sum::<f64>()
                * 2.0
                * PI
        };
        assert_relative_eq!(p.flux(), exact, max_relative = 2e-3);
    }

    #[test]
    fn a_narrow_beam_has_its_flux() {
        // 10000, 5000 and 0 cd at 0, 1 and 2 degrees (0 on to 90): 2 pi
        // int I sin.
        let file = "TILT=NONE\n1 -1 1 4 1 1 2 0 0 0\n1 1 0\n0 1 2 90\n0\n10000 5000 0 0\n";
        let p = parse(file.as_bytes()).unwrap();
        let n = 400_000;
        let exact = (0..n)
            .map(|i| {
                let g = (f64::from(i) + 0.5) * 2.0 / f64::from(n);
                let candela = if g <= 1.0 {
                    10000.0 - 5000.0 * g
                } else {
                    5000.0 * (2.0 - g)
                };
                candela * g.to_radians().sin() * (2.0 / f64::from(n)).to_radians()
            })
            .sum::<f64>()
            * 2.0
            * PI;
        assert_relative_eq!(p.flux(), exact, max_relative = 1e-6);
        // Every 1 degree out to 5: a beam Monte-Carlo-free.
        let file = "TILT=NONE\n1 -1 1 7 1 1 2 0 0 0\n1 1 0\n0 1 2 3 4 5 90\n0\n\
                    900 800 600 300 100 0 0\n";
        assert!(parse(file.as_bytes()).unwrap().flux() > 0.0);
    }

    #[test]
    fn symmetries_fold_the_horizontal_angle() {
        // Quadrant symmetric: C 0 and 90 differ.
        let file = "TILT=NONE\n1 -1 1 2 2 1 2 0 0 0\n1 1 0\n0 90\n0 90\n10 10 20 20\n";
        let p = parse(file.as_bytes()).unwrap();
        assert_relative_eq!(p.candela(0.0, 0.0), 10.0);
        assert_relative_eq!(p.candela(0.0, 90.0), 20.0);
        assert_relative_eq!(p.candela(0.0, 45.0), 15.0);
        assert_relative_eq!(p.candela(0.0, 135.0), 15.0);
        assert_relative_eq!(p.candela(0.0, 180.0), 10.0);
        assert_relative_eq!(p.candela(0.0, 270.0), 20.0);
        assert_relative_eq!(p.candela(0.0, -30.0), p.candela(0.0, 30.0));
        // Bilateral about 0-180.
        let file = "TILT=NONE\n1 -1 1 1 3 1 2 0 0 0\n1 1 0\n0\n0 90 180\n1 2 3\n";
        let p = parse(file.as_bytes()).unwrap();
        assert_relative_eq!(p.candela(0.0, 270.0), 2.0);
        assert_relative_eq!(p.candela(0.0, 315.0), 1.5);
        // Bilateral about 90-270.
        let file = "TILT=NONE\n1 -1 1 1 3 1 2 0 0 0\n1 1 0\n0\n90 180 270\n1 2 3\n";
        let p = parse(file.as_bytes()).unwrap();
        assert_relative_eq!(p.candela(0.0, 0.0), 2.0);
        assert_relative_eq!(p.candela(0.0, 45.0), 1.5);
        assert_relative_eq!(p.candela(0.0, 315.0), 2.5);
        // Full.
        let file = "TILT=NONE\n1 -1 1 1 5 1 2 0 0 0\n1 1 0\n0\n0 90 180 270 360\n1 2 3 4 1\n";
        let p = parse(file.as_bytes()).unwrap();
        assert_relative_eq!(p.candela(0.0, 315.0), 2.5);
    }

    #[test]
    fn bad_files_name_the_line_and_the_problem() {
        for (file, line, says) in [
            ("[TEST]\n1 2 3\n", 3, "no TILT= line"),
            ("TILT=INCLUDE\n", 1, "only TILT=NONE"),
            (
                "TILT=NONE\n1 -1 1 3 1 1 2 0 0 0\n",
                2,
                "the file ends before the ballast",
            ),
            (
                "TILT=NONE\n1 -1 1 x 1 1 2 0 0 0\n",
                2,
                "'x' is not a number",
            ),
            (
                "TILT=NONE\n1 -1 1 0 1 1 2 0 0 0\n1 1 0\n",
                2,
                "number of vertical angles is 0",
            ),
            ("TILT=NONE\n1 -1 1 2.5 1 1 2 0 0 0\n", 2, "whole number"),
            ("TILT=NONE\n1 -1 1 2 1 2 2 0 0 0\n1 1 0\n", 2, "type B"),
            (
                "TILT=NONE\n1 -1 1 2 1 7 2 0 0 0\n1 1 0\n",
                2,
                "photometric type 7",
            ),
            (
                "TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 0\n0 -5\n",
                4,
                "vertical angle -5",
            ),
            (
                "TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 0\n90 0\n",
                4,
                "must increase",
            ),
            (
                "TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 0\n0 60\n0\n1 1\n",
                4,
                "0-90, 0-180",
            ),
            (
                "TILT=NONE\n1 -1 1 2 2 1 2 0 0 0\n1 1 0\n0 90\n0 45\n1 1 1 1\n",
                5,
                "0-90, 0-180, 90-270",
            ),
            (
                "TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 0\n0 90\n0\n1 -1\n",
                6,
                "-1 is negative",
            ),
            (
                "TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 0\n0 90\n0\n1\n",
                6,
                "ends before a candela",
            ),
            (
                "TILT=NONE\n1 -1 1 2 1 1 2 0 0 0\n1 1 0\n0 90\n0\n1 1 7\n",
                6,
                "'7' after the last",
            ),
            (
                "TILT=NONE\n1 -1 inf 2 1 1 2 0 0 0\n",
                2,
                "not a finite number",
            ),
            (
                "TILT=NONE\n1 -1 -1 2 1 1 2 0 0 0\n1 1 0\n",
                2,
                "multiplier -1",
            ),
            (
                "TILT=NONE\n1 -1 1 5000 5000 1 2 0 0 0\n1 1 0\n",
                2,
                "more than 1000000",
            ),
        ] {
            let e = parse(file.as_bytes()).unwrap_err();
            assert_eq!(e.line, line, "{file:?}: {e}");
            assert!(e.message.contains(says), "{file:?}: {e}");
        }
    }
}
