//! # radiosity
//!
//! Progressive-refinement radiosity with ray-traced visibility: the algorithm
//! of Wallace, Elmquist & Haines (SIGGRAPH 1989) with the three improvements
//! of Wong & Tsang, *Three Improvements in the Ray Tracing Algorithm for
//! Progressive Radiosity* (HKU TR-93-05, 1993).

#![warn(missing_docs)]

pub mod accel;
pub mod app;
pub mod choice;
pub mod export;
pub mod final_gather;
pub mod form_factor;
pub mod geometry;
pub mod hemicube;
pub mod memory;
pub mod mesh;
pub mod photometry;
pub mod render;
pub mod scene;
pub mod sensors;
pub mod solver;
pub mod view;

pub use photometry::luminance;
