//! The command line, in ripgrep's two stages: flags as clap parses them
//! ([`args`], with the parsers of [`values`]), then a checked job
//! ([`job`]); and what a run shows while it works ([`progress`]).

pub mod args;
pub mod job;
pub mod progress;
pub mod values;
