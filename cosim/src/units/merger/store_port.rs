//! The store front end (`rtl_gen::merge::store_port_unit`, SPEC 8.15 "The
//! shared store port") against `golden::merge::merger::store_port`, and the store
//! model every bench of a shared port answers it with.
//!
//! The interleaving of reads on `store_req` depends on timing (which
//! requesters show a request in a cycle), so the store's answers cannot be
//! precomputed: [`StoreModel`] answers each `store_req` beat from the
//! store's contents after a fixed latency, with its own seeded stalls on
//! `store_req`'s ready and `store_resp`'s valid, stepped with the bench
//! ([`crate::tb::Reactor`]). What is checked bit for bit is what golden
//! defines: every requester's answers, in its order; a read outside the
//! store is an error of its own.

use std::collections::VecDeque;
use std::path::Path;

use golden::bits::Bits;
use golden::merge::merger::store_port::{
    store_port_transaction, StoreAddr, StoreArray, StorePortLayout, StorePortTransaction,
    StoreWords,
};
use golden::translate::stimulus::SplitMix64;
use rtl_gen::merge::StorePortConfig;

use crate::engine::Engine;
use crate::error::{CosimError, Result};
use crate::tb::{
    run_multi_stream_bench_reactive, stream_seed, BenchConfig, MultiReport, Reactor, StreamBeats,
    StreamDriver, StreamMonitor, StreamPorts,
};
use crate::units::multi_stream::ModuleEngine;

/// Where a [`StoreModel`] finds the word a read asks for: (the epoch, the
/// array, the address) to the word, None for a read outside the store.
pub type StoreLookup<'a> = dyn FnMut(usize, StoreArray, StoreAddr) -> Option<Bits> + 'a;

/// How a [`StoreModel`] tells the merge (epoch) a read is for: merges are
/// numbered by the beats of the bench's input `start_input` (the merger's
/// `cfg`), and a merge ends with its beat on output stream `end_output`
/// (`header`). A read's `slot` (its merge's number mod 2) names one of the
/// merges in flight (taken and not ended: two at most, SPEC 8.15); a slot
/// naming none is a failure.
#[derive(Clone, Debug)]
pub struct Epochs {
    /// The bench input whose beats start the merges.
    pub start_input: usize,
    /// The output stream whose beats end them.
    pub end_output: String,
    /// Merges started by the first `s` beats of `start_input`, per `s`
    /// (None: every beat starts one; the hierarchy unit's `cmd` carries
    /// determine commands between its merge commands).
    pub starts: Option<Vec<u64>>,
}

/// [`Epochs`] as a running model follows them.
struct EpochState {
    start_input: usize,
    starts: Option<Vec<u64>>,
    /// `<end_output>_valid` and `_ready`.
    end: (crate::design::PortId, crate::design::PortId),
    /// Merges taken (beats sent on `start_input`) and ended.
    taken: u64,
    ended: u64,
}

impl EpochState {
    /// The merge in flight whose number mod 2 is `slot`, or why none is.
    fn of_slot(&self, slot: u64) -> std::result::Result<usize, String> {
        let newest = self.taken.checked_sub(1).ok_or("no merge taken yet")?;
        let e = match newest % 2 == slot {
            true => newest,
            false => newest
                .checked_sub(1)
                .ok_or(format!("slot {slot}: only merge 0 was taken"))?,
        };
        match e >= self.ended {
            true => Ok(e as usize),
            false => Err(format!(
                "slot {slot}: merge {e}, whose header has left (merges {}..={newest} in flight)",
                self.ended
            )),
        }
    }
}

/// What a [`StoreModel`] saw.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct StoreStats {
    /// `store_req` beats taken (reads).
    pub reads: u64,
    /// Reads per epoch (a merge of the merger; one epoch for the front end alone).
    pub reads_by_epoch: Vec<u64>,
    /// The cycles of the first and the last read.
    pub first_read: u64,
    /// See `first_read`.
    pub last_read: u64,
    /// Per epoch: the cycles from its first read to its last, both
    /// counted (summed: [`Self::window_cycles`]).
    pub windows: Vec<(u64, u64)>,
    /// Reads outside the store (the first few, described).
    pub errors: Vec<String>,
    /// Reads outside the store in all.
    pub error_count: u64,
}

impl StoreStats {
    /// The cycles in which a merge was reading: those from some epoch's
    /// first read to its last (epochs that overlap count their common
    /// cycles once).
    pub fn window_cycles(&self) -> u64 {
        let mut w: Vec<(u64, u64)> = self.windows.iter().copied().filter(|w| w.0 > 0).collect();
        w.sort_unstable();
        let (mut total, mut end) = (0, 0);
        for (from, to) in w {
            let from = from.max(end + 1);
            if to >= from {
                total += to - from + 1;
                end = to;
            }
        }
        total
    }

    /// Reads per cycle from the first read to the last.
    pub fn busy_rate(&self) -> f64 {
        if self.reads == 0 {
            return 0.0;
        }
        self.reads as f64 / (self.last_read - self.first_read + 1) as f64
    }
}

/// A store on the `store_req` / `store_resp` ports of a design: it takes
/// a read when its `store_req` monitor is ready, answers it `latency`
/// clocks later (at the earliest) in order on `store_resp`, whose driver
/// stalls as the bench's inputs do.
pub struct StoreModel<'a> {
    layout: StorePortLayout,
    req: StreamMonitor,
    resp: StreamDriver,
    latency: u64,
    delayed: VecDeque<(u64, Bits)>,
    lookup: Box<StoreLookup<'a>>,
    /// The merges reads are attributed to (None: one epoch, 0).
    epochs: Option<EpochState>,
    /// What it saw.
    pub stats: StoreStats,
}

impl<'a> StoreModel<'a> {
    /// The store of `engine`'s design (ports `store_req`, `store_resp`) for
    /// grid layout `layout`, answering from `lookup` after `latency` clocks
    /// (`1..`), stalling with `config`'s patterns and seed; the epoch of a
    /// read is the merge of `epochs` its slot names (None: always 0).
    pub fn new(
        engine: &dyn Engine,
        layout: StorePortLayout,
        config: &BenchConfig,
        latency: u64,
        epochs: Option<Epochs>,
        lookup: Box<StoreLookup<'a>>,
    ) -> Result<StoreModel<'a>> {
        let ports = |name: &str| {
            StreamPorts::new(
                engine.design(),
                &format!("{name}_valid"),
                &format!("{name}_ready"),
                &[&format!("{name}_data")],
            )
        };
        // Seeds apart from every bench stream's (`stream_seed` of 0..).
        let seed = |j: usize| stream_seed(config.seed, 1000 + j);
        let epochs = match epochs {
            Some(e) => Some(EpochState {
                start_input: e.start_input,
                starts: e.starts,
                end: (
                    engine.port_id(&format!("{}_valid", e.end_output))?,
                    engine.port_id(&format!("{}_ready", e.end_output))?,
                ),
                taken: 0,
                ended: 0,
            }),
            None => None,
        };
        Ok(StoreModel {
            layout,
            req: StreamMonitor::new(
                ports("store_req")?,
                seed(0),
                config.out_stall_of("store_req"),
            )?,
            resp: StreamDriver::new(
                ports("store_resp")?,
                seed(1),
                config.in_stall_of("store_resp"),
            )?,
            latency: latency.max(1),
            delayed: VecDeque::new(),
            lookup,
            epochs,
            stats: StoreStats::default(),
        })
    }

    /// The answer to `beat` taken at `cycle`, and the epoch it is for
    /// (None: its slot names no merge in flight, a failure noted).
    fn answer(&mut self, beat: &Bits, cycle: u64) -> Result<(Bits, Option<usize>)> {
        let l = &self.layout;
        let read = l
            .unpack_req(beat)
            .map_err(|what| CosimError::Design { what })?;
        let (array, at) = (read.array, read.at);
        let epoch = match &self.epochs {
            None => Ok(0),
            Some(e) => e.of_slot(read.slot),
        };
        let found = match &epoch {
            Ok(e) => (self.lookup)(*e, array, at).ok_or(format!("(epoch {e}) outside the store")),
            Err(why) => Err(format!("for no merge in flight: {why}")),
        };
        let bits = match found {
            Ok(w) => l
                .pack_resp(&w)
                .map_err(|what| CosimError::Design { what })?,
            Err(why) => {
                self.stats.error_count += 1;
                if self.stats.errors.len() < 5 {
                    self.stats.errors.push(format!(
                        "cycle {cycle}: read of {array:?} hierarchy {} index {} {why}",
                        at.hier, at.index
                    ));
                }
                Bits::zero(l.resp_width)
            }
        };
        Ok((bits, epoch.ok()))
    }
}

impl StoreModel<'_> {
    /// Counts a read taken at `cycle` for `epoch` (None: for no merge in
    /// flight, counted in all only).
    fn count(&mut self, epoch: Option<usize>, cycle: u64) {
        let s = &mut self.stats;
        if s.reads == 0 {
            s.first_read = cycle;
        }
        s.reads += 1;
        s.last_read = cycle;
        let Some(e) = epoch else {
            return;
        };
        if s.reads_by_epoch.len() <= e {
            s.reads_by_epoch.resize(e + 1, 0);
        }
        s.reads_by_epoch[e] += 1;
        if s.windows.len() <= e {
            s.windows.resize(e + 1, (0, 0));
        }
        let w = &mut s.windows[e];
        if w.0 == 0 {
            w.0 = cycle;
        }
        w.1 = cycle;
    }
}

impl Reactor for StoreModel<'_> {
    fn drive(&mut self, engine: &mut dyn Engine, sent: &[u64]) -> Result<()> {
        if let Some(e) = self.epochs.as_mut() {
            let beats = sent.get(e.start_input).copied().unwrap_or(0);
            e.taken = match &e.starts {
                Some(s) => s.get(beats as usize).or(s.last()).copied().unwrap_or(0),
                None => beats,
            };
        }
        let now = engine.cycle();
        while self.delayed.front().is_some_and(|d| d.0 <= now) {
            let (_, word) = self.delayed.pop_front().expect("a front");
            self.resp.push(vec![word]);
        }
        self.resp.drive(engine)?;
        self.req.drive(engine)
    }

    fn observe(&mut self, engine: &dyn Engine) -> Result<bool> {
        let cycle = engine.cycle();
        let answered = self.resp.observe(engine)?.is_some();
        let read = self.req.observe(engine)?;
        // A read taken in the clock its merge's header leaves would be one
        // the header did not wait for: the read is attributed first.
        let moved = match read {
            None => answered,
            Some(txn) => {
                let (word, epoch) = self.answer(&txn[0], cycle)?;
                self.delayed.push_back((cycle + self.latency, word));
                self.count(epoch, cycle);
                true
            }
        };
        if let Some(e) = self.epochs.as_mut() {
            if engine.peek_bool(e.end.0)? && engine.peek_bool(e.end.1)? {
                e.ended += 1;
            }
        }
        Ok(moved)
    }

    fn finished(&self) -> bool {
        self.delayed.is_empty() && self.resp.pending() == 0
    }
}

/// A random run of the front end `c`: a store of `size` words per array
/// in each of 3 hierarchies (random bits), every requester reading
/// `1..=most` random addresses of it.
pub fn random_transaction(
    rng: &mut SplitMix64,
    c: &StorePortConfig,
    size: u64,
    most: u64,
) -> Result<(StoreWords, StorePortTransaction)> {
    let l = StorePortLayout::new(&c.params);
    let word = |rng: &mut SplitMix64, w: u32| -> Result<Bits> {
        let mut words: Vec<u64> = (0..w.div_ceil(64)).map(|_| rng.next_u64()).collect();
        if !w.is_multiple_of(64) {
            if let Some(last) = words.last_mut() {
                *last &= u64::MAX >> (64 - w % 64);
            }
        }
        Bits::from_words(&words, w).map_err(|e| CosimError::Design {
            what: e.to_string(),
        })
    };
    let hiers = 3.min(1u64 << l.hier.width);
    let mut store = StoreWords::default();
    for hier in 0..hiers {
        for index in 0..size {
            let at = StoreAddr { hier, index };
            store.insert(StoreArray::Node, at, word(rng, l.node_width)?);
            store.insert(StoreArray::Reference, at, word(rng, l.ref_width)?);
        }
    }
    let requests = c
        .arrays
        .iter()
        .map(|_| {
            let n = 1 + rng.next_u64() % most;
            (0..n)
                .map(|_| StoreAddr {
                    hier: rng.next_u64() % hiers,
                    index: rng.next_u64() % size,
                })
                .collect()
        })
        .collect();
    let tx = store_port_transaction(&c.arrays, requests, &store)
        .map_err(|what| CosimError::Design { what })?;
    Ok((store, tx))
}

/// What a run of the front end found.
#[derive(Debug)]
pub struct Outcome {
    /// The bench's report: every requester's answers compared.
    pub report: MultiReport,
    /// What the store saw.
    pub store: StoreStats,
    /// Cycles with `idle` high.
    pub idle_cycles: u64,
    /// `idle` in the last cycle.
    pub idle_at_end: bool,
}

impl Outcome {
    /// Every answer matched and arrived, nothing hung, no read outside the
    /// store, the port idle at the end.
    pub fn passed(&self) -> bool {
        self.report.passed() && self.store.error_count == 0 && self.idle_at_end
    }
}

/// Runs `tx` (with `store`) through the front end `c` on `engine`, the
/// Verilog written to `dir`; the store answers after `latency` clocks.
pub fn run(
    c: &StorePortConfig,
    engine: ModuleEngine,
    store: &StoreWords,
    tx: &StorePortTransaction,
    config: &BenchConfig,
    latency: u64,
    dir: &Path,
) -> Result<Outcome> {
    let module = rtl_gen::merge::store_port_unit(c).map_err(|what| CosimError::Design {
        what: format!("store port: {what}"),
    })?;
    let design = crate::from_rtl::design_from_module(&module, dir)?;
    let mut eng: Box<dyn Engine> = match engine {
        ModuleEngine::Ir => Box::new(crate::ir_engine::IrEngine::new(&module, &design)?),
        ModuleEngine::Verilator => {
            crate::open_engine(crate::EngineKind::Verilator, &design, false)?
        }
        ModuleEngine::Iverilog => crate::open_engine(crate::EngineKind::Icarus, &design, false)?,
    };
    let l = StorePortLayout::new(&c.params);
    let beats = |name: String, words: Vec<Bits>| StreamBeats {
        name,
        beats: words.into_iter().map(|w| vec![w]).collect(),
    };
    let mut inputs = Vec::new();
    let mut outputs = Vec::new();
    for (j, (reqs, resps)) in tx.requests.iter().zip(&tx.responses).enumerate() {
        let idx = reqs
            .iter()
            .map(|a| Ok(Bits::from_u64(l.addr_word(0, *a), l.addr.width())?))
            .collect::<Result<Vec<_>>>()?;
        inputs.push(beats(format!("r{j}_req"), idx));
        outputs.push(beats(format!("r{j}_resp"), resps.to_vec()));
    }
    let lookup = move |_: usize, a: StoreArray, at: StoreAddr| store.word(a, at).cloned();
    let mut model = StoreModel::new(&*eng, l, config, latency, None, Box::new(lookup))?;
    let (report, watch) = run_multi_stream_bench_reactive(
        eng.as_mut(),
        &inputs,
        &outputs,
        config,
        &["idle"],
        &mut model,
    )?;
    Ok(Outcome {
        report,
        store: model.stats,
        idle_cycles: watch.counts.first().map_or(0, |c| c.1),
        idle_at_end: watch.at_end.first().is_some_and(|c| c.1),
    })
}
