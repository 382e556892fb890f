//! Receiver refinement inside one solve (src/solver/resume.rs): the coarse
//! pass goes on on the refined mesh instead of a second solve from the
//! start.
//!
//! * A shot replayed to a receiver gives what the shot gave it: the coarse
//!   pass's shots replayed to sensors at its own vertices' points give
//!   those vertices' irradiance (emitting patches, the sun, overshooting).
//! * The ledger balances to round-off when the solve goes on and after
//!   every shot since, and the answer is the same to the bit with one and
//!   three threads.
//! * Going on agrees with solving again on the same refined mesh, within
//!   what the stopping rule leaves unshot.

mod common;

use glam::DVec3;
use radiosity::mesh::Mesh;
use radiosity::scene::{self, Scene};
use radiosity::solver::refine::refine_base;
use radiosity::solver::{Flow, MethodSettings, Settings, Solver, Start, vertex_receivers};

/// The solve of `scene` on `mesh` going on from `start`.
fn resumed<'a>(scene: &'a Scene, mesh: &'a Mesh, settings: &Settings, start: Start) -> Solver<'a> {
    let occluder = settings.accel.build(&scene.surfaces);
    Solver::resume(scene, mesh, settings.clone(), start, occluder)
}

/// The default settings at `scale` times the scene's element size.
fn settings_for(scene: &Scene, scale: f64) -> Settings {
    let mut settings = Settings::adaptive();
    let sizes = scene.default_mesh_sizes();
    settings.mesh.patch_size = sizes.patch_size;
    settings.mesh.element_size = scale * sizes.element_size;
    settings
}

/// The coarse pass's shots (`shots` of them, recorded) replayed to sensors
/// at its vertices' own points, on a mesh with every other element split:
/// each sensor reads what its vertex gathered, to 1e-9 of the largest.
fn replay_reads_what_was_gathered(scene: &Scene, settings: &Settings, shots: u64) {
    let base = Mesh::build(scene, &settings.mesh).unwrap();
    let mut coarse_settings = settings.clone();
    coarse_settings.max_shots = Some(shots);
    coarse_settings.converge = 1e-9;
    let mut coarse = Solver::new(scene, &base, coarse_settings);
    assert!(coarse.record_shots());
    coarse.run(|_| Flow::Continue);
    assert_eq!(coarse.stats().shots, shots);
    let depths: Vec<u8> = (0..base.elements.len()).map(|e| (e % 2) as u8).collect();
    let (refined, parents) = base
        .refine_with_parents(&depths, usize::MAX, settings.mesh.element_size)
        .unwrap();
    assert!(refined.vertices.len() > base.vertices.len());
    let sensors = vertex_receivers(scene, &base);
    let start = coarse
        .go_on(&refined, &parents, sensors)
        .expect("adaptive shooting replays its shots");
    let resumed = resumed(scene, &refined, settings, start);
    let gathered = coarse.irradiance();
    let largest = gathered.iter().map(|e| e.max_element()).fold(0.0, f64::max);
    assert!(largest > 0.0);
    for (v, (replayed, had)) in resumed.sensor_irradiance().iter().zip(gathered).enumerate() {
        assert!(
            (*replayed - *had).abs().max_element() <= 1e-9 * largest,
            "vertex {v}: replayed {replayed} against {had}"
        );
    }
    // The old vertices keep theirs.
    assert_eq!(&resumed.irradiance()[..gathered.len()], gathered);
    common::assert_ledger_balances(&resumed);
}

#[test]
fn replayed_shots_give_what_they_gave() {
    let cornell = scene::load("cornell").unwrap();
    replay_reads_what_was_gathered(&cornell, &settings_for(&cornell, 2.0), 6);
    let mut overshooting = settings_for(&cornell, 2.0);
    let MethodSettings::Adaptive(adaptive) = &mut overshooting.method else {
        panic!("the default method is adaptive shooting");
    };
    adaptive.overshoot = 1.0;
    replay_reads_what_was_gathered(&cornell, &overshooting, 6);
    let sun = common::board_in_the_sun();
    let mut settings = Settings::adaptive();
    settings.mesh.patch_size = 1.0;
    settings.mesh.element_size = 0.5;
    replay_reads_what_was_gathered(&sun, &settings, 4);
}

/// The whole refinement as a render runs it, at one and three threads:
/// the coarse pass goes on (it replayed something), the ledger balances
/// from the moment it does and after every shot, and both answers are the
/// same to the bit.
fn goes_on_balanced_and_alike(scene: &Scene, settings: &Settings) {
    let solve_with = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let base = Mesh::build(scene, &settings.mesh).unwrap();
                let mut refined = refine_base(scene, settings, base, None, &[]).unwrap();
                assert!(refined.split_elements > 0);
                let start = refined.start.take().expect("the coarse pass goes on");
                assert!(start.replayed_receivers > 0 && start.replayed_shots > 0);
                let mut solver = resumed(scene, &refined.mesh, settings, start);
                common::assert_ledger_balances(&solver);
                solver.run(|s| {
                    common::assert_ledger_balances(s);
                    Flow::Continue
                });
                (solver.stats().shots, solver.radiosity().to_vec())
            })
    };
    let (shots_one, one) = solve_with(1);
    let (shots_three, three) = solve_with(3);
    assert_eq!(shots_one, shots_three);
    assert!(one.iter().zip(&three).all(|(a, b)| a == b));
}

#[test]
fn going_on_balances_and_ignores_the_thread_count() {
    let cornell = scene::load("cornell").unwrap();
    let mut settings = settings_for(&cornell, 2.0);
    settings.max_shots = Some(60);
    goes_on_balanced_and_alike(&cornell, &settings);
    // A sun: its shadow's edge crosses split elements, whose pieces are
    // integrated afresh.
    let sun = common::board_in_the_sun();
    let mut settings = Settings::adaptive();
    settings.mesh.patch_size = 1.0;
    settings.mesh.element_size = 0.5;
    settings.max_shots = Some(40);
    goes_on_balanced_and_alike(&sun, &settings);
}

/// Going on and solving again on the same refined mesh, both to the
/// default stopping rule; vertex radiosity compared by L1 over the
/// vertices, relative to their mean.
///
/// * `exact`: the coarse pass made only the emitters' shots, which are the
///   fresh solve's first shots (the same light sent from the same
///   elements), so going on reaches the fresh solve's state after them and
///   from there both make the same shots: the same count, and radiosity
///   the same to 1e-12. Any error in the replay, the pieces' unshot
///   radiosity or the ledger would show.
/// * Otherwise the coarse pass's later shooters were chosen among the
///   base mesh's clusters, the fresh solve's among the refined mesh's, and
///   both orders end within the stopping rule: L1 within twice the
///   unshot fraction it leaves.
fn agrees_with_solving_again(scene: &Scene, settings: &Settings, exact: bool) {
    let base = Mesh::build(scene, &settings.mesh).unwrap();
    let mut refined = refine_base(scene, settings, base, None, &[]).unwrap();
    assert!(refined.split_elements > 0);
    let start = refined.start.take().unwrap();
    let mut resumed = resumed(scene, &refined.mesh, settings, start);
    resumed.run(|_| Flow::Continue);
    let mut again = Solver::new(scene, &refined.mesh, settings.clone());
    again.run(|_| Flow::Continue);
    let (a, b) = (resumed.radiosity(), again.radiosity());
    let mean: f64 = b.iter().map(|x| radiosity::luminance(*x)).sum::<f64>() / b.len() as f64;
    let l1: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (radiosity::luminance(*x) - radiosity::luminance(*y)).abs())
        .sum::<f64>()
        / b.len() as f64
        / mean;
    println!(
        "{}: {} elements split, {} coarse shots; L1 {l1:e}; shots {} against {}",
        scene.name,
        refined.split_elements,
        refined.coarse_shots,
        resumed.stats().shots,
        again.stats().shots
    );
    if exact {
        assert_eq!(resumed.stats().shots, again.stats().shots);
        assert!(l1 < 1e-12, "L1 {l1}");
    } else {
        assert!(l1 < 2.0 * settings.converge, "L1 {l1}");
    }
}

#[test]
fn going_on_agrees_with_solving_again() {
    let cornell = scene::load("cornell").unwrap();
    agrees_with_solving_again(&cornell, &settings_for(&cornell, 2.0), true);
    let room = scene::load("room").unwrap();
    agrees_with_solving_again(&room, &settings_for(&room, 1.0), false);
    let mut sun = common::board_in_the_sun();
    sun.name = "board in the sun".into();
    let mut settings = Settings::adaptive();
    settings.mesh.patch_size = 1.0;
    settings.mesh.element_size = 0.5;
    agrees_with_solving_again(&sun, &settings, true);
}

/// Sensors given to the refinement are gathered at from the start: a
/// sensor at a vertex's point reads what the vertex reads once the solve
/// has gone on and finished.
#[test]
fn sensors_given_to_the_refinement_are_replayed_too() {
    let scene = scene::load("cornell").unwrap();
    let mut settings = settings_for(&scene, 2.0);
    settings.max_shots = Some(30);
    let base = Mesh::build(&scene, &settings.mesh).unwrap();
    let points: Vec<DVec3> = base.vertices.iter().map(|v| v.position).collect();
    let sensors = vertex_receivers(&scene, &base);
    let mut refined = refine_base(&scene, &settings, base, None, &sensors).unwrap();
    let start = refined.start.take().unwrap();
    let mut solver = resumed(&scene, &refined.mesh, &settings, start);
    solver.run(|_| Flow::Continue);
    let at_vertices = &solver.irradiance()[..points.len()];
    for (v, (s, e)) in solver
        .sensor_irradiance()
        .iter()
        .zip(at_vertices)
        .enumerate()
    {
        assert!(
            (*s - *e).abs().max_element() <= 1e-9 * e.max_element().max(1e-12),
            "vertex {v}: sensor {s} against {e}"
        );
    }
}
