//! The command line, in ripgrep's two stages: flags as clap parses them
//! ([`args`], with the parsers of [`values`]), then a checked job
//! ([`job`]); and what a run shows while it works ([`progress`]), to a
//! person or, as JSON events, to a program ([`events`]).

pub mod args;
pub mod events;
pub mod job;
pub mod progress;
pub mod values;
