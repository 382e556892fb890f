//! A solve the device cannot hold (`Backend::check`, the GPU's memory
//! estimate against its limits and `--max-gpu-memory`): asked for by name
//! it is one clear error before anything is written; taken because it was
//! there (`--device auto`) the run goes on on the CPU, with a note.

use std::path::Path;
use std::sync::Arc;

use radiosity::app::{self, Error, ImageJob, Job};
use radiosity::final_gather::FinalGather;
use radiosity::mesh::Mesh;
use radiosity::render::Exposure;
use radiosity::scene::{LoadOptions, Scene};
use radiosity::solver::Settings;
use radiosity::solver::device::{AdaptiveSolve, AdaptiveTransfers, Backend, Device, DeviceError};

/// A device too small for anything.
struct Tiny;

impl Backend for Tiny {
    fn name(&self) -> String {
        "tiny device".into()
    }

    fn refuses(&self, _: &Settings) -> Option<String> {
        None
    }

    fn adaptive(&self, _: &AdaptiveSolve<'_>) -> Result<Box<dyn AdaptiveTransfers>, DeviceError> {
        panic!("a solve it cannot hold must not start on it")
    }

    fn segments(
        &self,
        _: &Scene,
    ) -> Result<Box<dyn radiosity::solver::device::Segments>, DeviceError> {
        Err(DeviceError("no segments on this device".into()))
    }

    fn check(&self, _: &Scene, mesh: &Mesh, receivers: usize) -> Result<u64, DeviceError> {
        Err(DeviceError(format!(
            "{} elements and {receivers} receivers do not fit",
            mesh.elements.len()
        )))
    }
}

fn job(dir: &Path, device: Device) -> Job {
    Job {
        scene: "cornell".into(),
        settings: Settings {
            max_shots: Some(5),
            device,
            ..Settings::adaptive()
        },
        patch_size: None,
        element_size: None,
        final_gather: FinalGather::Direct,
        image: Some(ImageJob {
            path: dir.join("out.png"),
            width: 16,
            height: 12,
            camera: None,
            supersampling: 1,
            exposure: Exposure::Auto { ev: 0.0 },
            ambient: true,
        }),
        vertices_csv: None,
        stats_json: None,
        load: LoadOptions::default(),
        bake: None,
        ply: None,
        sensors: None,
        max_memory: None,
    }
}

#[test]
fn a_solve_the_device_cannot_hold_is_an_error_or_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let asked = app::run(&job(dir.path(), Device::backend(Arc::new(Tiny))), &mut ());
    match asked {
        Err(e @ Error::Device(_)) => {
            let message = e.to_string();
            assert!(message.starts_with("--device gpu: "), "{message}");
            assert!(message.contains("do not fit"), "{message}");
        }
        other => panic!("expected the device's error, got {other:?}"),
    }
    assert!(!dir.path().join("out.png").exists());
    let taken = app::run(&job(dir.path(), Device::preferred(Arc::new(Tiny))), &mut ()).unwrap();
    assert_eq!(taken.device.name, None, "the solve ran on the CPU");
    assert_eq!(taken.stats.shots, 5);
    let note: Vec<&String> = taken
        .warnings
        .iter()
        .filter(|w| w.starts_with("--device auto: ") && w.contains("do not fit"))
        .collect();
    assert_eq!(note.len(), 1, "{:?}", taken.warnings);
    assert!(dir.path().join("out.png").exists());
}
