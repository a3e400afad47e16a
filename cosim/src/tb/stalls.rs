//! Stall patterns: when a driver leaves `valid` low and a monitor holds
//! `ready` low (SpinalHDL's `StreamDriver` / `StreamReadyRandomizer`, and
//! longer shapes than a coin per cycle).
//!
//! A pattern ([`Stalls`]) is a value; a [`StallGen`] is its state in one
//! stream, drawing from that stream's seeded [`Prng`] one decision per
//! opportunity (a monitor: every cycle; a driver: every cycle it could raise
//! `valid` for a new beat). Every engine takes its decisions from here (the
//! stepped bench, the translate bench, the Icarus batches' masks and gaps),
//! so all three see the same stalls for the same seed. The coin draws
//! exactly as the bench always did, so a coin run is the run it was.

use super::prng::Prng;
use std::fmt;

/// The longest run of stalls (bursty) or period (periodic) a pattern may
/// ask for: well inside the 1000-cycle watchdog even when a driver's and a
/// monitor's stall runs follow each other.
pub const MAX_RUN: u32 = 200;

/// The largest coin probability: above it a stream moves so rarely that a
/// run is all waiting.
pub const MAX_COIN: f64 = 0.9;

/// How a stream stalls.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Stalls {
    /// Never.
    None,
    /// Each decision a coin: stall with probability `p` (0..=0.9).
    Coin(f64),
    /// Alternating runs of stalls and of go, their lengths uniform in
    /// `1..=stall` and `1..=go` (drawn from the seed when a run starts).
    Bursty {
        /// Longest stall run.
        stall: u32,
        /// Longest go run.
        go: u32,
    },
    /// `stall` of every `every` decisions, consecutively, at a phase drawn
    /// from the seed.
    Periodic {
        /// Stalls per period.
        stall: u32,
        /// Period length.
        every: u32,
    },
}

impl Stalls {
    /// The defaults of `bursty` and `periodic` without parameters.
    pub const BURSTY: Stalls = Stalls::Bursty { stall: 16, go: 16 };
    /// See [`Stalls::BURSTY`].
    pub const PERIODIC: Stalls = Stalls::Periodic { stall: 1, every: 3 };

    /// Refuses parameters outside the stated ranges, saying which.
    pub fn check(&self) -> Result<(), String> {
        let run = |what: &str, v: u32| {
            if (1..=MAX_RUN).contains(&v) {
                Ok(())
            } else {
                Err(format!("{self}: {what} {v}: expected 1..={MAX_RUN}"))
            }
        };
        match *self {
            Stalls::None => Ok(()),
            Stalls::Coin(p) if (0.0..=MAX_COIN).contains(&p) => Ok(()),
            Stalls::Coin(p) => Err(format!(
                "stall probability {p}: expected 0 <= P <= {MAX_COIN}"
            )),
            Stalls::Bursty { stall, go } => {
                run("longest stall run", stall).and_then(|_| run("longest go run", go))
            }
            Stalls::Periodic { stall, every } => {
                run("period", every)?;
                if stall >= every {
                    return Err(format!(
                        "{self}: {stall} stalls of every {every}: expected fewer stalls than the period"
                    ));
                }
                Ok(())
            }
        }
    }

    /// Parses `none`, `coin[:P]`, `bursty[:S,G]` or `periodic[:K/N]`
    /// (`coin` alone: probability `coin`), checked.
    pub fn parse(text: &str, coin: f64) -> Result<Stalls, String> {
        let (name, arg) = match text.split_once(':') {
            Some((n, a)) => (n, Some(a)),
            None => (text, None),
        };
        let num = |s: &str| {
            s.trim()
                .parse::<u32>()
                .map_err(|_| format!("`{text}`: `{s}`: expected an unsigned integer"))
        };
        let pair = |a: &str, sep: char, form: &str| -> Result<(u32, u32), String> {
            let (x, y) = a
                .split_once(sep)
                .ok_or_else(|| format!("`{text}`: expected {form}"))?;
            Ok((num(x)?, num(y)?))
        };
        let s = match (name, arg) {
            ("none", None) => Stalls::None,
            ("coin", None) => Stalls::Coin(coin),
            ("coin", Some(p)) => Stalls::Coin(
                p.trim()
                    .parse()
                    .map_err(|_| format!("`{text}`: expected coin:P, P a number"))?,
            ),
            ("bursty", None) => Stalls::BURSTY,
            ("bursty", Some(a)) => {
                let (stall, go) = pair(a, ',', "bursty:S,G (longest stall and go runs)")?;
                Stalls::Bursty { stall, go }
            }
            ("periodic", None) => Stalls::PERIODIC,
            ("periodic", Some(a)) => {
                let (stall, every) = pair(a, '/', "periodic:K/N (K stalls of every N)")?;
                Stalls::Periodic { stall, every }
            }
            _ => {
                return Err(format!(
                    "`{text}`: expected none, coin[:P], bursty[:S,G] or periodic[:K/N]"
                ))
            }
        };
        s.check()?;
        Ok(s)
    }

    /// True for the coin (whose probability `--stall` gives).
    pub fn is_coin(&self) -> bool {
        matches!(self, Stalls::Coin(_))
    }
}

/// No stalls, as a bench without a pattern runs.
impl Default for Stalls {
    fn default() -> Self {
        Stalls::None
    }
}

/// The canonical text, which [`Stalls::parse`] reads back.
impl fmt::Display for Stalls {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Stalls::None => write!(f, "none"),
            Stalls::Coin(p) => write!(f, "coin:{p}"),
            Stalls::Bursty { stall, go } => write!(f, "bursty:{stall},{go}"),
            Stalls::Periodic { stall, every } => write!(f, "periodic:{stall}/{every}"),
        }
    }
}

/// Patterns for named streams, each replacing the bench's pattern of its
/// side (inputs or outputs) on that stream alone: a unit's outputs held in
/// long runs while its inputs flow, which stalling every stream alike
/// never gives.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StreamStalls {
    streams: Vec<(String, Stalls)>,
}

impl StreamStalls {
    /// None: every stream takes its side's pattern.
    pub fn is_empty(&self) -> bool {
        self.streams.is_empty()
    }

    /// The named streams and their patterns, in the order given.
    pub fn iter(&self) -> impl Iterator<Item = (&str, Stalls)> {
        self.streams.iter().map(|(n, s)| (n.as_str(), *s))
    }

    /// Reads `NAME=PATTERN` items ([`Stalls::parse`]'s patterns, a coin
    /// with its probability), refusing a malformed item, a bad pattern or a
    /// stream named twice, saying which.
    pub fn parse<'a>(items: impl IntoIterator<Item = &'a str>) -> Result<StreamStalls, String> {
        let mut streams: Vec<(String, Stalls)> = Vec::new();
        for item in items {
            let (name, pattern) = item
                .split_once('=')
                .filter(|(n, _)| !n.is_empty())
                .ok_or_else(|| {
                    format!("`{item}`: expected STREAM=PATTERN, e.g. header=bursty:200,2")
                })?;
            if pattern == "coin" {
                return Err(format!(
                    "`{item}`: a coin here takes its probability: coin:P"
                ));
            }
            let stalls = Stalls::parse(pattern, 0.0).map_err(|e| format!("`{item}`: {e}"))?;
            if streams.iter().any(|(n, _)| n == name) {
                return Err(format!("`{item}`: stream `{name}` is named twice"));
            }
            streams.push((name.to_string(), stalls));
        }
        Ok(StreamStalls { streams })
    }

    /// The pattern of stream `name`: its own, else `side` (its side's).
    pub fn of(&self, name: &str, side: Stalls) -> Stalls {
        self.streams
            .iter()
            .find(|(n, _)| n == name)
            .map_or(side, |(_, s)| *s)
    }

    /// Refuses a name that is none of `streams` (a design's), listing them.
    pub fn check_names<'a>(
        &self,
        streams: impl Iterator<Item = &'a str> + Clone,
    ) -> Result<(), String> {
        for (name, _) in &self.streams {
            if !streams.clone().any(|s| s == name) {
                let known: Vec<&str> = streams.collect();
                return Err(format!(
                    "a stall pattern for stream `{name}`, which the design does not have; its streams: {}",
                    known.join(", ")
                ));
            }
        }
        Ok(())
    }
}

/// `NAME=PATTERN` items separated by spaces, which [`StreamStalls::parse`]
/// reads back item by item.
impl fmt::Display for StreamStalls {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (k, (name, s)) in self.streams.iter().enumerate() {
            let sep = if k == 0 { "" } else { " " };
            write!(f, "{sep}{name}={s}")?;
        }
        Ok(())
    }
}

/// A pattern's state in one stream.
#[derive(Clone, Debug)]
pub struct StallGen {
    pattern: Stalls,
    started: bool,
    stalling: bool,
    left: u32,
}

impl StallGen {
    /// The state before the first decision.
    pub fn new(pattern: Stalls) -> StallGen {
        StallGen {
            pattern,
            started: false,
            stalling: false,
            left: 0,
        }
    }

    /// The next decision: true to go (raise `valid` / `ready`), false to
    /// stall, drawing from `rng` as the pattern needs.
    pub fn go(&mut self, rng: &mut Prng) -> bool {
        match self.pattern {
            Stalls::None => true,
            Stalls::Coin(p) => !rng.chance(p),
            Stalls::Bursty { stall, go } => {
                if !self.started {
                    self.started = true;
                    self.stalling = rng.below(2) == 0;
                    self.left = self.run(rng, stall, go);
                } else if self.left == 0 {
                    self.stalling = !self.stalling;
                    self.left = self.run(rng, stall, go);
                }
                self.left -= 1;
                !self.stalling
            }
            Stalls::Periodic { stall, every } => {
                // `left` is the position in the period, 0..every.
                if !self.started {
                    self.started = true;
                    self.left = rng.below(u64::from(every)) as u32;
                } else {
                    self.left = (self.left + 1) % every;
                }
                self.left >= stall
            }
        }
    }

    fn run(&self, rng: &mut Prng, stall: u32, go: u32) -> u32 {
        let most = if self.stalling { stall } else { go };
        1 + rng.below(u64::from(most)) as u32
    }

    /// The next 64 decisions as a word, bit `k` the `k`-th (1 = go): a mask
    /// block of the Icarus batches.
    pub fn go_word(&mut self, rng: &mut Prng) -> u64 {
        (0..64).fold(0u64, |w, k| w | (u64::from(self.go(rng)) << k))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` decisions of `pattern` from `seed`.
    fn mask(pattern: Stalls, seed: u64, n: usize) -> Vec<bool> {
        let (mut g, mut rng) = (StallGen::new(pattern), Prng::new(seed));
        (0..n).map(|_| g.go(&mut rng)).collect()
    }

    /// The lengths of the runs of `want` in `m` (the first and last cut
    /// runs left out).
    fn runs(m: &[bool], want: bool) -> Vec<usize> {
        let mut out = Vec::new();
        let mut len = 0;
        let mut first = true;
        for w in m.windows(2) {
            if w[0] == want {
                len += 1;
            }
            if w[0] == want && w[1] != want {
                if !first {
                    out.push(len);
                }
                len = 0;
            }
            if w[0] != w[1] {
                first = false;
            }
        }
        out
    }

    fn mean(v: &[usize]) -> f64 {
        v.iter().sum::<usize>() as f64 / v.len() as f64
    }

    #[test]
    fn the_coin_draws_as_the_bench_always_did() {
        let m = mask(Stalls::Coin(0.3), 9, 2000);
        let mut rng = Prng::new(9);
        let old: Vec<bool> = (0..2000).map(|_| !rng.chance(0.3)).collect();
        assert_eq!(m, old);
        assert!(mask(Stalls::None, 9, 500).iter().all(|&g| g));
    }

    #[test]
    fn bursty_runs_are_long_bounded_and_spread_as_asked() {
        let m = mask(Stalls::Bursty { stall: 40, go: 10 }, 3, 200_000);
        let (s, g) = (runs(&m, false), runs(&m, true));
        assert!(s.len() > 1000 && g.len() > 1000, "{} {}", s.len(), g.len());
        // Uniform in 1..=S: mean (S + 1) / 2, every length reached, none longer.
        assert!((mean(&s) - 20.5).abs() < 1.0, "stall mean {}", mean(&s));
        assert!((mean(&g) - 5.5).abs() < 0.4, "go mean {}", mean(&g));
        assert_eq!(s.iter().max(), Some(&40));
        assert_eq!(g.iter().max(), Some(&10));
        assert_eq!(s.iter().min(), Some(&1));
        // A coin of the same share of stalls has runs of about 1 / (1 - p).
        let share = m.iter().filter(|&&g| !g).count() as f64 / m.len() as f64;
        assert!((share - 20.5 / 26.0).abs() < 0.02, "{share}");
        let c = mask(Stalls::Coin(share.min(MAX_COIN)), 3, 200_000);
        assert!(mean(&runs(&c, false)) < 6.0, "{}", mean(&runs(&c, false)));
    }

    #[test]
    fn periodic_stalls_k_of_every_n_in_one_run() {
        for seed in [1, 2, 3] {
            let m = mask(Stalls::Periodic { stall: 3, every: 7 }, seed, 7000);
            let (s, g) = (runs(&m, false), runs(&m, true));
            assert!(s.iter().all(|&l| l == 3), "{s:?}");
            assert!(g.iter().all(|&l| l == 4), "{g:?}");
            for p in m.chunks(7) {
                assert_eq!(p.iter().filter(|&&g| !g).count(), 3);
            }
        }
        // The phase comes from the seed.
        let phases: std::collections::BTreeSet<usize> = (0..40)
            .map(|seed| {
                mask(Stalls::PERIODIC, seed, 3)
                    .iter()
                    .position(|&g| !g)
                    .unwrap()
            })
            .collect();
        assert_eq!(phases.len(), 3, "{phases:?}");
    }

    #[test]
    fn parse_reads_back_what_display_writes_and_refuses_the_rest() {
        for s in [
            Stalls::None,
            Stalls::Coin(0.25),
            Stalls::Bursty { stall: 5, go: 200 },
            Stalls::Periodic { stall: 0, every: 1 },
            Stalls::BURSTY,
            Stalls::PERIODIC,
        ] {
            assert_eq!(Stalls::parse(&s.to_string(), 0.3), Ok(s));
        }
        assert_eq!(Stalls::parse("coin", 0.4), Ok(Stalls::Coin(0.4)));
        for (text, want) in [
            ("bursty:0,4", "longest stall run 0: expected 1..=200"),
            ("bursty:4,201", "longest go run 201: expected 1..=200"),
            ("bursty:4", "expected bursty:S,G"),
            ("periodic:3/3", "expected fewer stalls than the period"),
            ("periodic:1/0", "period 0"),
            ("periodic:-1/4", "`-1`: expected an unsigned integer"),
            ("coin:0.95", "expected 0 <= P <= 0.9"),
            (
                "sometimes",
                "expected none, coin[:P], bursty[:S,G] or periodic[:K/N]",
            ),
        ] {
            let e = Stalls::parse(text, 0.3).unwrap_err();
            assert!(e.contains(want), "{text}: {e}");
        }
    }

    #[test]
    fn stream_stalls_replace_their_streams_pattern_alone() {
        let s = StreamStalls::parse(["header=bursty:200,2", "nodes=none"]).unwrap();
        assert_eq!(
            s.of("header", Stalls::Coin(0.3)),
            Stalls::Bursty { stall: 200, go: 2 }
        );
        assert_eq!(s.of("nodes", Stalls::Coin(0.3)), Stalls::None);
        assert_eq!(s.of("cfg", Stalls::PERIODIC), Stalls::PERIODIC);
        let text = s.to_string();
        assert_eq!(text, "header=bursty:200,2 nodes=none");
        assert_eq!(StreamStalls::parse(text.split(' ')), Ok(s.clone()));
        assert_eq!(
            s.check_names(["cfg", "header", "nodes"].into_iter()),
            Ok(())
        );
        let e = s.check_names(["cfg", "nodes"].into_iter()).unwrap_err();
        assert!(
            e.contains("stream `header`") && e.contains("its streams: cfg, nodes"),
            "{e}"
        );
        for (item, want) in [
            ("header", "expected STREAM=PATTERN"),
            ("=none", "expected STREAM=PATTERN"),
            ("header=coin", "coin:P"),
            ("header=bursty:0,2", "longest stall run 0"),
        ] {
            let e = StreamStalls::parse([item]).unwrap_err();
            assert!(e.contains(want), "{item}: {e}");
        }
        let e = StreamStalls::parse(["a=none", "a=coin:0.5"]).unwrap_err();
        assert!(e.contains("named twice"), "{e}");
    }
}
