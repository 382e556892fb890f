//! The `radiosity` command: parses flags ([`cli::args`]) into a validated
//! [`radiosity::app::Job`] ([`cli::job`]) and calls [`radiosity::app::run`].
//! All logic lives in the library.

use std::net::SocketAddr;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{Context, Result, anyhow};
use clap::Parser;
use clap::error::ErrorKind;

mod cli;
mod serve;

use cli::args::{Cli, Command, ExperimentArgs, RenderArgs, ServeArgs, ViewArgs};
use cli::progress::{ProgressDisplay, print_summary};
use radiosity::app;
use radiosity::scene::{Limits, builtin};
use radiosity_experiments as experiments;

fn main() -> ExitCode {
    // Adapters are ranked by the GPU back end itself; Mesa's device-select
    // Vulkan layer, which would rank them too, connects to a display server
    // to do so and, on a headless machine, prints errors for nothing. Set
    // before any thread exists, as `set_var` requires.
    if std::env::var_os("NODEVICE_SELECT").is_none() {
        // SAFETY: the process has one thread yet.
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        // An option's value checked by one of the parsers above: one line
        // in the words of that parser, like every other bad input.
        Err(e) if e.kind() == ErrorKind::ValueValidation => {
            // Our own checks name their option; other parsers' words (an
            // address, a number) go with clap's line, which names it.
            match std::error::Error::source(&e).map(|s| s.to_string()) {
                Some(source) if source.contains("--") => eprintln!("error: {source}"),
                _ => eprintln!(
                    "{}",
                    e.render().to_string().lines().next().unwrap_or("error")
                ),
            }
            return ExitCode::FAILURE;
        }
        Err(e) => e.exit(),
    };
    match real_main(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {}", message(&error));
            ExitCode::FAILURE
        }
    }
}

/// An error and its causes on one line, each cause once: a cause whose
/// text the message already holds (an I/O error a library message quotes)
/// is not repeated.
fn message(error: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in error.chain() {
        let part = cause.to_string();
        if text.contains(&part) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&part);
    }
    text
}

fn real_main(cli: Cli) -> Result<()> {
    match cli.command {
        Some(Command::Scenes) => {
            for (name, description) in builtin::list() {
                println!("{name:10} {description}");
            }
            Ok(())
        }
        Some(Command::Render(args)) => render(&args),
        Some(Command::Experiment(args)) => experiment(&args),
        Some(Command::Serve(args)) => serve(&args),
        Some(Command::ExportScene(args)) => {
            for path in app::export_scene(
                &args.scene,
                &args.out,
                &args.load.options(Limits::default()),
            )? {
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        Some(Command::View(args)) => view(&args),
        None => render(&RenderArgs::parse_from(["radiosity"])),
    }
}

/// Most worker threads `--threads` accepts.
const MAX_THREADS: usize = 1024;

/// A rayon pool with `threads` workers (default: every core).
fn pool(threads: Option<usize>) -> Result<rayon::ThreadPool> {
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(threads) = threads {
        if !(1..=MAX_THREADS).contains(&threads) {
            return Err(anyhow!(
                "--threads must be between 1 and {MAX_THREADS}, not {threads}"
            ));
        }
        pool = pool.num_threads(threads);
    }
    pool.build().context("cannot start worker threads")
}

fn experiment(args: &ExperimentArgs) -> Result<()> {
    let context = experiments::Context {
        out: args.out.clone(),
        quick: args.quick,
        command: std::env::args()
            .enumerate()
            .map(|(i, a)| if i == 0 { "radiosity".to_string() } else { a })
            .collect::<Vec<_>>()
            .join(" "),
        scenes: args.scenes.clone(),
        embree_python: args.embree_python.clone(),
        reference: args.reference.clone(),
        device: args.device.into(),
    };
    let written = pool(args.threads)?
        .install(|| experiments::run(&args.names, &context, |name| eprintln!("running {name}")))?;
    for path in written {
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// Prints warnings about the flags a job does not use.
fn warn_unused(warnings: &[String]) {
    for warning in warnings {
        eprintln!("warning: {warning}");
    }
}

fn render(args: &RenderArgs) -> Result<()> {
    let mut events = args
        .progress_json
        .as_deref()
        .map(cli::events::Events::open)
        .transpose()?;
    let result = render_with(args, &mut events);
    if let (Some(events), Err(e)) = (&mut events, &result) {
        events.error(e);
    }
    result
}

/// [`render`], its events written to `events` (taken by the progress
/// display during the run and given back for the last one).
fn render_with(args: &RenderArgs, events: &mut Option<cli::events::Events>) -> Result<()> {
    let (job, warnings) = args.job()?;
    warn_unused(&warnings);
    app::validate(&job)?;
    let pool = pool(args.threads)?;
    let stops = stop_handlers()?;
    if let Some(path) = &args.stop_file {
        cli::events::watch_stop_file(path.clone(), Arc::clone(&stops.interrupted))?;
    }
    let mut display =
        ProgressDisplay::new(args.quiet, stops.interrupted, stops.abort).with_events(events.take());
    let outcome = pool.install(|| app::run(&job, &mut display));
    display.finish();
    *events = display.take_events();
    let outcome = outcome?;
    for warning in &outcome.warnings {
        eprintln!("warning: {warning}");
    }
    // Events on standard output take the place of the summary there.
    let events_on_stdout = args.progress_json.as_deref() == Some(std::path::Path::new("-"));
    if !args.quiet && !events_on_stdout {
        print_summary(&outcome);
    }
    if !outcome.unwritten.is_empty() {
        let names: Vec<String> = outcome
            .unwritten
            .iter()
            .map(|p| p.display().to_string())
            .collect();
        return Err(anyhow!(
            "stopped before the final pass was done: {} not written{}",
            names.join(", "),
            if outcome.written.is_empty() {
                String::new()
            } else {
                format!(
                    " (written: {})",
                    outcome
                        .written
                        .iter()
                        .map(|p| p.display().to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            }
        ));
    }
    if let Some(events) = events {
        events.done(&outcome);
    }
    Ok(())
}

/// The flags a render's stops raise.
struct Stops {
    /// Raised by the first Ctrl-C (and `--stop-file`): the solve stops and
    /// every output is written from the state reached.
    interrupted: Arc<AtomicBool>,
    /// Raised by a second Ctrl-C, or SIGTERM or SIGHUP at any stage: the
    /// run ends at once, writing only the outputs already complete.
    abort: Arc<AtomicBool>,
}

/// Ctrl-C once asks the solve to stop after the current shot and write its
/// outputs from the state reached (the final pass included); a second ends
/// the run at once (the final pass left where it is), writing only the
/// outputs already complete; a third exits there and then, writing nothing.
/// SIGTERM and SIGHUP do what the second Ctrl-C does, at any stage; a
/// second one exits there and then.
fn stop_handlers() -> Result<Stops> {
    let stops = Stops {
        interrupted: Arc::new(AtomicBool::new(false)),
        abort: Arc::new(AtomicBool::new(false)),
    };
    let (interrupted, abort) = (Arc::clone(&stops.interrupted), Arc::clone(&stops.abort));
    let count = std::sync::atomic::AtomicUsize::new(0);
    ctrlc::set_handler(move || match count.fetch_add(1, Ordering::SeqCst) {
        0 => {
            interrupted.store(true, Ordering::SeqCst);
            eprintln!(
                "\nstopping and writing the outputs from the state reached (Ctrl-C again ends \
                 at once, writing only the outputs complete)"
            );
        }
        1 => {
            interrupted.store(true, Ordering::SeqCst);
            abort.store(true, Ordering::SeqCst);
            eprintln!(
                "\nending: writing only the outputs complete (Ctrl-C again exits writing \
                 nothing)"
            );
        }
        _ => {
            eprintln!("\naborted: no output written");
            std::process::exit(130);
        }
    })
    .context("cannot install the Ctrl-C handler")?;
    #[cfg(unix)]
    {
        use signal_hook::consts::{SIGHUP, SIGTERM};
        let mut signals = signal_hook::iterator::Signals::new([SIGTERM, SIGHUP])
            .context("cannot install the SIGTERM handler")?;
        let (interrupted, abort) = (Arc::clone(&stops.interrupted), Arc::clone(&stops.abort));
        std::thread::spawn(move || {
            for signal in signals.forever() {
                if abort.swap(true, Ordering::SeqCst) && signal == SIGTERM {
                    eprintln!("\naborted: no output written");
                    std::process::exit(143);
                }
                interrupted.store(true, Ordering::SeqCst);
                eprintln!("\nending: writing only the outputs complete");
            }
        });
    }
    Ok(stops)
}

fn view(args: &ViewArgs) -> Result<()> {
    let server = serve::viewer::Viewer::bind(&args.file, args.port)?;
    println!("serving {} at {}", args.file.display(), server.url());
    println!("open that address in a browser; Ctrl-C stops");
    server.run()?;
    Ok(())
}

fn serve(args: &ServeArgs) -> Result<()> {
    if args.render.progress_json.is_some() || args.render.stop_file.is_some() {
        return Err(anyhow!(
            "--progress-json and --stop-file are for `render`: `serve` shows its progress and \
             its stop button in the browser"
        ));
    }
    let (job, warnings) = args.render.job()?;
    warn_unused(&warnings);
    app::validate(&job)?;
    let pool = pool(args.render.threads)?;
    let server = serve::Server::start(
        SocketAddr::new(args.host, args.port),
        serve::Display {
            camera: job.image.as_ref().and_then(|i| i.camera),
            ambient: !args.render.no_ambient,
            exposure: args.render.exposure,
            final_gather: job.final_gather,
        },
        &args.pause_at,
    )?;
    // The first Ctrl-C stops the solve and writes the outputs; a second
    // one gives up at once.
    let handle = server.handle();
    let interrupts = std::sync::atomic::AtomicUsize::new(0);
    ctrlc::set_handler(move || {
        if interrupts.fetch_add(1, std::sync::atomic::Ordering::SeqCst) == 0 {
            handle.shutdown();
        } else {
            std::process::exit(130);
        }
    })
    .context("cannot install the Ctrl-C handler")?;
    // SIGTERM and SIGHUP as Ctrl-C: the first stops and writes, a second
    // exits there and then.
    #[cfg(unix)]
    {
        use signal_hook::consts::{SIGHUP, SIGTERM};
        let mut signals = signal_hook::iterator::Signals::new([SIGTERM, SIGHUP])
            .context("cannot install the SIGTERM handler")?;
        let handle = server.handle();
        std::thread::spawn(move || {
            for (k, _) in signals.forever().enumerate() {
                if k == 0 {
                    handle.shutdown();
                } else {
                    std::process::exit(143);
                }
            }
        });
    }
    println!("serving {}", server.url());
    if !args.render.quiet {
        eprintln!("open it in a browser; Ctrl-C stops the solve, writes the outputs and quits");
    }

    let outcome = pool.install(|| app::run(&job, &mut server.observer()));
    let outcome = match outcome {
        Ok(outcome) => outcome,
        Err(error) => {
            server.close();
            return Err(error.into());
        }
    };
    for warning in &outcome.warnings {
        eprintln!("warning: {warning}");
    }
    if !args.render.quiet {
        print_summary(&outcome);
    }
    server.finished(&outcome);
    if !server.shutdown_requested() && !args.render.quiet {
        eprintln!(
            "still serving the final state at {}; Ctrl-C quits",
            server.url()
        );
    }
    server.wait();
    Ok(())
}
