//! Writes a simulated CARMEN laser log of a robot wandering an office
//! floor (see `pirouette::sim::OfficeFloor`), as large as asked: the input
//! of `benches/big-log.sh`, and a log with ground truth for trying the
//! laser mapping (`pirouette eval laser` scores against its poses).
//!
//! ```sh
//! cargo run --release --example office_log -- --megabytes 100 office.log
//! ```

use anyhow::{bail, Context, Result};
use clap::Parser;
use pirouette::sim::{LogSim, LogWriter, OfficeFloor};
use std::io::Write;
use std::path::PathBuf;

/// A simulated laser log of an office floor.
#[derive(Parser, Debug)]
struct Args {
    /// The log to write (an existing file is replaced).
    out: PathBuf,
    /// Stop after the scan that takes the log past this size.
    #[arg(long, default_value_t = 10)]
    megabytes: u64,
    /// Blocks of offices across and up.
    #[arg(long, default_value_t = 4)]
    blocks: usize,
    /// A 180° scanner of 180 beams (`FLASER`) instead of a 270° one of
    /// 1,081 (`ROBOTLASER1`).
    #[arg(long)]
    sick: bool,
    /// Seed of the crates, the route and the noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// Counts the bytes written through it.
struct Counting<W> {
    inner: W,
    bytes: u64,
}

impl<W: Write> Write for Counting<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.inner.write(buf)?;
        self.bytes += n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush()
    }
}

fn main() -> Result<()> {
    let args = Args::parse();
    if args.blocks == 0 || args.blocks > 100 {
        bail!("--blocks {}: between 1 and 100", args.blocks);
    }
    let floor = OfficeFloor {
        columns: args.blocks,
        rows: args.blocks,
        ..OfficeFloor::default()
    };
    let sim = if args.sick {
        LogSim::sick()
    } else {
        LogSim::hokuyo()
    };
    let walls = floor.walls(args.seed);
    let limit = args.megabytes.saturating_mul(1_000_000);
    let tmp = args.out.with_extension("part");
    let file = std::fs::File::create(&tmp).with_context(|| format!("{}: cannot create", tmp.display()))?;
    let mut out = Counting {
        inner: std::io::BufWriter::new(file),
        bytes: 0,
    };
    let mut log = LogWriter::new(&sim, &walls, args.seed)?;
    log.header(&mut out)?;
    // The wanderer never stops; the log does once it is large enough.
    let mut path = floor.wander(args.seed).peekable();
    while out.bytes < limit {
        let Some(p) = path.next() else { break };
        log.scan(&mut out, &p, path.peek(), false)?;
    }
    out.flush()?;
    drop(out);
    std::fs::rename(&tmp, &args.out).with_context(|| format!("{}: cannot write", args.out.display()))?;
    eprintln!(
        "{}: {} scans of a {} × {} block office floor",
        args.out.display(),
        log.scans,
        args.blocks,
        args.blocks
    );
    Ok(())
}
