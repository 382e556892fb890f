//! Shots in rounds (`--round`, src/solver/adaptive/round.rs) against
//! closed forms and the paper's loop of one shooter at a time:
//!
//! * the furnace's exact answer, the ledger balanced after every round;
//! * the built-in room: the same radiosity as one shooter at a time solved
//!   far tighter, in a tenth of the steps, for at most 1.2 times the node
//!   visits and rays (counted, never timed);
//! * the direct part booked shooter by shooter, in rounds that mix a lamp
//!   still unshot with lit walls;
//! * the settings: the fraction's range.

mod common;

use common::{assert_ledger_balances, quad};
use glam::DVec3;
use radiosity::mesh::Mesh;
use radiosity::scene::{self, Scene};
use radiosity::solver::{Flow, MethodSettings, Settings, Solver, StopReason};

/// The default settings with `--round` fraction, solved to `converge`, on the
/// base mesh.
fn settings(fraction: f64, converge: f64) -> Settings {
    common::adaptive_on_base_mesh(converge, |a| a.round = fraction)
}

fn sized(scene: &Scene, settings: Settings) -> Settings {
    common::sized_for(scene, settings)
}

/// What a solve gave and cost.
struct Solved {
    radiosity: Vec<DVec3>,
    irradiance: Vec<DVec3>,
    direct: Vec<DVec3>,
    rounds: u64,
    shots: u64,
    /// Node visits and shadow rays.
    work: u64,
}

/// Solves to the stopping rule, checking the ledger after every round.
fn solve(scene: &Scene, settings: &Settings) -> Solved {
    let mesh = Mesh::build(scene, &settings.mesh).unwrap();
    let mut solver = Solver::new(scene, &mesh, settings.clone());
    solver.run(|s| {
        assert_ledger_balances(s);
        Flow::Continue
    });
    // Black walls leave nothing unshot once the lamps have shot.
    assert!(matches!(
        solver.stop_reason(),
        Some(StopReason::Converged | StopReason::NothingUnshot)
    ));
    assert!(solver.direct_complete());
    Solved {
        radiosity: solver.radiosity().to_vec(),
        irradiance: solver.irradiance()[..mesh.vertices.len()].to_vec(),
        direct: solver.direct_irradiance()[..mesh.vertices.len()].to_vec(),
        rounds: solver.stats().rounds,
        shots: solver.stats().shots,
        work: solver.count("walk_node_visits") + solver.stats().rays_cast,
    }
}

/// The closed furnace (rho 0.5, E 1: radiosity 2 everywhere) in rounds:
/// every vertex within 1% of 2, in fewer rounds than shooters shot.
#[test]
fn the_furnace_converges_to_its_closed_form_in_rounds() {
    let furnace = common::furnace(1.0, 0.5, 1.0);
    let mut s = settings(0.7, 1e-3);
    s.mesh.patch_size = 0.5;
    s.mesh.element_size = 0.125;
    let solved = solve(&furnace, &s);
    println!(
        "furnace: {} rounds of {} shots",
        solved.rounds, solved.shots
    );
    assert!(solved.rounds * 4 <= solved.shots);
    for b in &solved.radiosity {
        for c in 0..3 {
            assert!((b[c] - 2.0).abs() < 0.02, "radiosity {b} is not 2");
        }
    }
}

/// The built-in room (lamps, a window's daylight, shadows) at the default
/// stopping rule: in rounds of the default fraction, within 0.6% (L1) of
/// one shooter at a time taken to 1e-4 unshot, as near as one shooter at
/// a time lands at the default stopping rule; in at most a tenth of its
/// steps, for at most 1.2 times its node visits and rays.
#[test]
fn rounds_land_where_one_shooter_at_a_time_does() {
    let room = scene::load("room").unwrap();
    let default_round = match Settings::adaptive().method {
        MethodSettings::Adaptive(a) => a.round,
        _ => unreachable!("the default method is adaptive shooting"),
    };
    assert!(default_round < 1.0, "the default shoots in rounds");
    let converge = Settings::adaptive().converge;
    let tight = solve(&room, &sized(&room, settings(1.0, 1e-4)));
    let single = solve(&room, &sized(&room, settings(1.0, converge)));
    let rounds = solve(&room, &sized(&room, settings(default_round, converge)));
    let (single_error, round_error) = (
        common::l1(&single.radiosity, &tight.radiosity),
        common::l1(&rounds.radiosity, &tight.radiosity),
    );
    println!(
        "room: L1 against the tight solve {round_error} in {} rounds ({} shots, work {}), \
         {single_error} one at a time ({} shots, work {})",
        rounds.rounds, rounds.shots, rounds.work, single.shots, single.work
    );
    assert!(single_error < 0.006, "one at a time: {single_error}");
    assert!(round_error < 0.006, "rounds: {round_error}");
    assert_eq!(single.rounds, single.shots);
    assert!(
        10 * rounds.rounds <= single.rounds,
        "{} rounds against {} one at a time",
        rounds.rounds,
        single.rounds
    );
    assert!(
        5 * rounds.work <= 6 * single.work,
        "work {} in rounds against {} one at a time",
        rounds.work,
        single.work
    );
}

/// A closed box lit by nine small lamps under its ceiling, each half as
/// bright as the one before: the dimmer lamps are left out of the first
/// rounds and shoot with the walls the brighter ones lit. Each shooter's
/// direct part is its own emission's share of what it sent, so the direct
/// light booked in rounds is what one shooter at a time books (to the
/// refinement's sampling, which follows the power sent), and it is the
/// lamps' light alone: a solve with the walls black gives the same.
#[test]
fn rounds_book_each_shooter_s_direct_light_apart() {
    let lamps = |rho: f64| {
        let mut lit = common::furnace(1.0, rho, 0.0);
        for k in 0..9 {
            let face = lit.surfaces.len() as u32;
            let (i, j) = (f64::from(k % 3), f64::from(k / 3));
            let lamp = quad(
                DVec3::new(0.1 + 0.3 * i, 0.999, 0.1 + 0.3 * j),
                DVec3::X * 0.2,
                DVec3::Z * 0.2,
                0.0,
                100.0 * 0.5f64.powi(k),
                face,
            );
            assert!(lamp.normal.abs_diff_eq(-DVec3::Y, 1e-12));
            lit.surfaces.push(lamp);
        }
        lit
    };
    let at = |fraction: f64| {
        let mut s = settings(fraction, 1e-3);
        s.mesh.patch_size = 0.25;
        s.mesh.element_size = 0.0625;
        s
    };
    let in_rounds = solve(&lamps(0.7), &at(0.7));
    let one_by_one = solve(&lamps(0.7), &at(1.0));
    let walls_black = solve(&lamps(0.0), &at(0.7));
    let (against_one, against_black, of_all) = (
        common::l1(&in_rounds.direct, &one_by_one.direct),
        common::l1(&in_rounds.direct, &walls_black.direct),
        common::l1(&in_rounds.direct, &in_rounds.irradiance),
    );
    println!(
        "lamps: {} rounds of {} shots; direct L1 against one at a time {against_one}, against \
         black walls {against_black}; of all the light {of_all}",
        in_rounds.rounds, in_rounds.shots
    );
    assert!(in_rounds.rounds < in_rounds.shots);
    assert!(against_one < 1e-9, "{against_one}");
    assert!(against_black < 1e-9, "{against_black}");
    // The direct part is not all the light.
    assert!(of_all > 0.2, "{of_all}");
}

/// `--round` outside (0, 1] is refused.
#[test]
fn settings_refuse_a_fraction_outside_zero_to_one() {
    for f in [0.0, -0.5, 1.5, f64::NAN] {
        assert!(settings(f, 1e-3).validate().is_err(), "{f}");
    }
    for f in [0.01, 0.7, 1.0] {
        assert!(settings(f, 1e-3).validate().is_ok(), "{f}");
    }
}
