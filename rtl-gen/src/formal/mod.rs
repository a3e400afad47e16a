//! Formal proofs (SPEC.md section 11.1): the properties of a module written
//! once, as a [`Proof`], and emitted as a separate SystemVerilog property
//! harness (`<module>_formal.sv`) that instantiates the module's unchanged
//! Verilog-2005, plus a SymbiYosys job (`<module>.sby`) with one task per
//! [`Check`].
//!
//! The harness sees only the module's ports, except where a proof names an
//! internal net as `dut.<net>` (an induction invariant or a slot of a
//! buffer): those are connected by Yosys' `flatten` through `hierconn` wires,
//! so the design file stays exactly what `gen` emits.
//!
//! ```
//! use rtl_gen::formal::{units, Check};
//! let p = units::skid_buffer(8);
//! let sv = p.harness().unwrap();
//! assert!(sv.contains("module skid_buffer_w8_formal"));
//! assert!(p.sby(&["skid_buffer_w8.v".into()], None, 60).contains("[tasks]"));
//! assert!(p.checks.iter().any(|(c, _, _)| *c == Check::Flow));
//! ```

mod harness;
pub mod units;

use crate::Module;

/// One group of properties; each is one SymbiYosys task.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Check {
    /// Output streams hold `valid` and `data` until `ready` (input streams
    /// assumed to do the same).
    Handshake,
    /// The proof's [`Flow`]s: no beat lost, duplicated, invented or reordered.
    Flow,
    /// Outputs are determined after reset: two copies of the module from
    /// independent arbitrary states, one reset cycle, the same inputs, agree
    /// on every control output, and on every stream's data while it is valid.
    Determined,
    /// `idle` and `done` mean what SPEC.md says ([`Status`]).
    Status,
}

impl Check {
    /// Every check, in report order.
    pub const ALL: [Check; 4] = [
        Check::Handshake,
        Check::Flow,
        Check::Determined,
        Check::Status,
    ];

    /// The task name (also the `CHECK_<NAME>` define of the harness).
    pub fn name(self) -> &'static str {
        match self {
            Check::Handshake => "handshake",
            Check::Flow => "flow",
            Check::Determined => "determined",
            Check::Status => "status",
        }
    }
}

/// How a check is run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Bounded model checking from reset to the proof's depth: no trace of
    /// that many cycles violates a property.
    Bmc,
    /// k-induction with k = the proof's depth (the base case is the BMC of
    /// the same depth): a proof for traces of every length.
    Induction,
}

impl Mode {
    /// `bmc` or `prove` (SymbiYosys' mode names).
    pub fn sby_mode(self) -> &'static str {
        match self {
            Mode::Bmc => "bmc",
            Mode::Induction => "prove",
        }
    }

    /// How the report names it.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Bmc => "bmc",
            Mode::Induction => "k-induction",
        }
    }
}

/// Where beats go. Expressions are SystemVerilog over the module's ports
/// and `dut.<net>` internal nets.
#[derive(Clone, Debug)]
pub enum Flow {
    /// Every beat taken on `input` leaves on `output` unchanged, once, in
    /// order, with at most `capacity` inside; while any is inside, `output`
    /// is valid. Checked on one beat the solver chooses (any beat). For
    /// induction, `occupancy` is the design's count of beats inside and
    /// `slots[i]` the data of the `i`-th oldest.
    Fifo {
        /// Input stream name.
        input: String,
        /// Output stream name.
        output: String,
        /// Most beats inside.
        capacity: u32,
        /// The design's own count of beats inside (an invariant).
        occupancy: Option<String>,
        /// The data of the `i`-th oldest beat inside, oldest first.
        slots: Vec<String>,
    },
    /// A merge without buffering: in every cycle, a beat leaves on `output`
    /// exactly when one input transfers, it is that input's beat, and that
    /// input is the lowest-numbered valid one unless `output` stalled the
    /// cycle before (then the handshake check says it is the beat offered).
    Priority {
        /// Input streams, highest priority first.
        inputs: Vec<String>,
        /// Output stream.
        output: String,
    },
    /// Events counted: each `input` event (e.g. an `End` beat taken) is
    /// answered by one `output` event (e.g. a result beat leaving), in
    /// order, never an answer without its event, at most `capacity`
    /// outstanding. `name` labels its properties.
    Counted {
        /// Label of the properties (an identifier).
        name: String,
        /// The event asked (a one-bit expression).
        input: String,
        /// The event answering it.
        output: String,
        /// Most outstanding.
        capacity: u32,
        /// The design's own count outstanding (an invariant).
        occupancy: Option<String>,
    },
}

/// The status outputs' meaning.
#[derive(Clone, Debug, Default)]
pub struct Status {
    /// The `idle` port, if the module has one: high exactly when every
    /// flow of `busy` has nothing outstanding (counted from the transfers of
    /// earlier cycles).
    pub idle: Option<String>,
    /// The `done` port, if it pulses as `idle` rises: `idle` now and not
    /// idle the cycle before, low in the first cycle after reset.
    pub done: Option<String>,
    /// Indices into [`Proof::flows`] whose occupancy is "a transaction
    /// inside".
    pub busy: Vec<usize>,
    /// Input streams taken only while idle.
    pub only_when_idle: Vec<String>,
    /// A state in which the unit works ahead for a transaction it has not
    /// taken yet (the level fetcher's PREFETCH, SPEC 8.13): an expression
    /// as in [`Status::rules`], and the input streams also taken then.
    /// `idle` and it never hold together, and one of them holds exactly
    /// when every flow of `busy` has nothing outstanding.
    pub ahead: Option<(String, Vec<String>)>,
    /// Further promises of the status outputs, `(label, expression)`:
    /// SystemVerilog over ports, `dut.<net>` and the flows' counters
    /// (`f<j>_occ`), checked in every cycle after reset; one with `$past`
    /// from the second.
    pub rules: Vec<(String, String)>,
}

/// A promise of the environment, assumed: SystemVerilog over ports,
/// `dut.<net>`, the flows' counters (`f<j>_occ`) and the trackers
/// (`t_<name>`), in every cycle after reset.
#[derive(Clone, Debug)]
pub struct Assumption {
    /// Its label (an identifier): the harness names it `a_<label>`.
    pub label: String,
    /// The expression assumed true.
    pub expr: String,
    /// The checks that assume it; empty: every check. A promise only one
    /// check needs is kept out of the others, which then hold for more
    /// environments.
    pub checks: Vec<Check>,
}

/// A register of the harness on the environment's side, for a promise that
/// needs history (e.g. the nodes a stream has sent since its last `End`):
/// zero in the reset cycle, then `next` each clock. It watches the ports
/// (and may read `dut.<net>`); the design never sees it.
#[derive(Clone, Debug)]
pub struct Tracker {
    /// Its name (an identifier): the harness declares `t_<name>`.
    pub name: String,
    /// Width in bits.
    pub width: u32,
    /// Its next value: SystemVerilog over what an [`Assumption`] reads.
    pub next: String,
}

/// The properties of one module and how each check is run.
pub struct Proof {
    /// The module, as `gen` emits it.
    pub module: Module,
    /// Input streams (`<name>_valid`, `_ready`, `_data`), assumed to hold
    /// `valid` and `data` until `ready`.
    pub inputs: Vec<String>,
    /// Output streams, proven to.
    pub outputs: Vec<String>,
    /// What the flow check proves.
    pub flows: Vec<Flow>,
    /// What the status check proves.
    pub status: Option<Status>,
    /// Invariants over internal nets, asserted in every check (so they are
    /// proven too) to make induction converge.
    pub invariants: Vec<(String, String)>,
    /// What the environment promises beyond the input handshakes (e.g. a
    /// store answers only reads it has taken).
    pub assumptions: Vec<Assumption>,
    /// Environment-side registers the promises read, in order.
    pub trackers: Vec<Tracker>,
    /// The checks run: how, and to what depth (BMC depth, or k of
    /// k-induction).
    pub checks: Vec<(Check, Mode, u32)>,
    /// The depth of a check added by [`Proof::check`].
    pub depth: u32,
}

impl Proof {
    /// A proof of `module` with no checks yet.
    pub fn new(module: Module, inputs: &[&str], outputs: &[&str], depth: u32) -> Proof {
        Proof {
            module,
            inputs: inputs.iter().map(|s| s.to_string()).collect(),
            outputs: outputs.iter().map(|s| s.to_string()).collect(),
            flows: Vec::new(),
            status: None,
            invariants: Vec::new(),
            assumptions: Vec::new(),
            trackers: Vec::new(),
            checks: Vec::new(),
            depth,
        }
    }

    /// Adds `check`, run in `mode` to the proof's depth.
    pub fn check(self, check: Check, mode: Mode) -> Proof {
        let depth = self.depth;
        self.check_to(check, mode, depth)
    }

    /// Adds `check`, run in `mode` to `depth`.
    pub fn check_to(mut self, check: Check, mode: Mode, depth: u32) -> Proof {
        self.checks.push((check, mode, depth));
        self
    }

    /// Adds a flow.
    pub fn flow(mut self, flow: Flow) -> Proof {
        self.flows.push(flow);
        self
    }

    /// Adds the environment's promise `label` (an identifier), assumed in
    /// `checks` (empty: every check).
    pub fn assume(mut self, label: &str, expr: &str, checks: &[Check]) -> Proof {
        self.assumptions.push(Assumption {
            label: label.to_string(),
            expr: expr.to_string(),
            checks: checks.to_vec(),
        });
        self
    }

    /// Adds the tracker `t_<name>` of `width` bits, `next` its next value.
    pub fn tracker(mut self, name: &str, width: u32, next: &str) -> Proof {
        self.trackers.push(Tracker {
            name: name.to_string(),
            width,
            next: next.to_string(),
        });
        self
    }

    /// Adds an invariant named `label` (an identifier).
    pub fn invariant(mut self, label: &str, expr: &str) -> Proof {
        self.invariants.push((label.to_string(), expr.to_string()));
        self
    }

    /// The module's name.
    pub fn name(&self) -> String {
        self.module.name()
    }

    /// The harness module's name.
    pub fn harness_name(&self) -> String {
        format!("{}_formal", self.module.name())
    }

    /// The SystemVerilog property harness; refuses a proof that names a
    /// port or internal net the module does not have.
    pub fn harness(&self) -> Result<String, String> {
        harness::emit(self)
    }

    /// The SymbiYosys job: `design` are the module's Verilog files (children
    /// first), the harness is `<harness_name>.sv` beside them; `depth`
    /// overrides every check's; `timeout` (seconds) ends a task as TIMEOUT.
    pub fn sby(&self, design: &[String], depth: Option<u32>, timeout: u32) -> String {
        let mut s =
            String::from("# generated by rtl-gen (rtl-gen/src/formal); do not edit\n[tasks]\n");
        for (c, _, _) in &self.checks {
            s += &format!("{}\n", c.name());
        }
        s += "\n[options]\n";
        for (c, m, d) in &self.checks {
            let d = depth.unwrap_or(*d);
            s += &format!("{0}: mode {1}\n{0}: depth {d}\n", c.name(), m.sby_mode());
        }
        s += &format!(
            "multiclock off\ntimeout {timeout}\n\n[engines]\nsmtbmc boolector\n\n[script]\n"
        );
        for f in design {
            s += &format!("read_verilog {f}\n");
        }
        let top = self.harness_name();
        for (c, _, _) in &self.checks {
            s += &format!(
                "{}: read_verilog -formal -DCHECK_{} {top}.sv\n",
                c.name(),
                c.name().to_uppercase()
            );
        }
        // `flatten` before `prep` connects the harness' `dut.<net>` wires.
        s += &format!("hierarchy -top {top}\nproc\nflatten\nprep -top {top}\n\n[files]\n");
        for f in design {
            s += &format!("{f}\n");
        }
        s += &format!("{top}.sv\n");
        s
    }
}

#[cfg(test)]
mod tests {
    use super::{units, Check, Flow, Mode, Proof, Status};

    #[test]
    fn every_proof_has_a_harness_and_a_task_per_check() {
        for name in units::NAMES.iter().chain(&units::LARGE) {
            let p = units::by_name(name).unwrap();
            let sv = p.harness().unwrap_or_else(|e| panic!("{name}: {e}"));
            let sby = p.sby(&[format!("{}.v", p.name())], None, 60);
            for (c, m, d) in &p.checks {
                let define = format!("CHECK_{}", c.name().to_uppercase());
                assert!(sv.contains(&format!("`ifdef {define}")), "{name}: {define}");
                assert!(
                    sby.contains(&format!(
                        "{0}: mode {1}\n{0}: depth {d}\n",
                        c.name(),
                        m.sby_mode()
                    )),
                    "{name}"
                );
            }
            // The design is instantiated, never copied into the harness.
            assert!(sv.contains(&format!("    {} dut (", p.name())), "{name}");
            assert!(!sv.contains(&format!("module {} (", p.name())), "{name}");
        }
    }

    #[test]
    fn rules_and_assumptions_are_emitted_under_their_labels() {
        let p = units::store_port();
        let sv = p.harness().unwrap();
        assert!(
            sv.contains("a_store_answers_reads_taken: assume(!store_resp_valid || f3_occ != 0);"),
            "{sv}"
        );
        assert!(sv.contains("p_store_resp_taken_in_flight: assert("), "{sv}");
        assert!(
            sv.contains(
                "p_idle_means_empty: assert(idle == (f0_occ == 0 && f1_occ == 0 && f2_occ == 0));"
            ),
            "{sv}"
        );
        // A rule with `$past` is checked from the second cycle after reset.
        let sv = units::hierarchy_merger_per_node_small().harness().unwrap();
        let clocked = sv
            .split("always @(posedge clk) if (f_prev) begin")
            .nth(1)
            .unwrap();
        assert!(
            clocked.starts_with("\n        p_done_pulse: assert("),
            "{sv}"
        );
        assert!(
            clocked.contains("p_done_after_header: assert(done == $past("),
            "{sv}"
        );
        // The level fetcher's PREFETCH: idle or prefetching exactly when no
        // command is in progress, `cmd` taken in either, `cfg` only idle;
        // the per-node fetcher takes `cmd` only while idle.
        let sv = units::fetcher_small().harness().unwrap();
        let ahead = r"((\dut.phase  == 3'd1 || \dut.phase  == 3'd2 || \dut.phase  == 3'd5) && !\dut.cmd_have )";
        for p in [
            format!("p_idle_not_ahead: assert(!(idle && {ahead}));"),
            format!("p_idle_means_empty: assert((idle || {ahead}) == (f0_occ == 0));"),
            format!("p_cmd_only_when_idle_or_ahead: assert(!cmd_ready || idle || {ahead});"),
            "p_cfg_only_when_idle: assert(!cfg_ready || idle);".into(),
        ] {
            assert!(sv.contains(&p), "{p} in {sv}");
        }
        let pn = units::fetcher_per_node_small().harness().unwrap();
        assert!(
            pn.contains("p_cmd_only_when_idle: assert(!cmd_ready || idle);"),
            "{pn}"
        );
        // A counted flow's asking side may be a number.
        assert!(
            sv.contains("wire [3:0] f1_in = cmd_valid && cmd_ready ? ("),
            "{sv}"
        );
        let mut p = units::skid_buffer(8);
        p.status = Some(Status {
            done: Some("done".into()),
            ..Status::default()
        });
        let e = p.harness().unwrap_err();
        assert!(e.contains("need `idle`"), "{e}");
    }

    #[test]
    fn trackers_are_declared_first_and_a_promise_of_one_check_is_under_its_define() {
        let sv = units::record_writer_small().harness().unwrap();
        let regs = sv.find("    reg [7:0] t_l0_nodes;").expect("declared");
        let next = sv
            .find("        t_l0_nodes <= rst ? 8'd0 : (")
            .expect("zero in the reset cycle");
        // Every tracker is declared before any is assigned (a `next` may
        // read a later one).
        assert!(regs < next && sv[..next].contains("reg [10:0] t_ended_crefs;"));
        let promise = sv.find("a_top_has_nodes: assume(").unwrap();
        let define = sv[..promise].rfind("`ifdef CHECK_DETERMINED\n").unwrap();
        assert!(!sv[define..promise].contains("`endif"), "{sv}");
        assert_eq!(sv.matches("a_top_has_nodes: assume(").count(), 1);
        // A promise of every check is under no define.
        let sv = units::store_port().harness().unwrap();
        let promise = sv.find("a_store_answers_reads_taken").unwrap();
        let opened = sv[..promise].matches("`ifdef").count();
        assert_eq!(opened, sv[..promise].matches("`endif").count(), "{sv}");
        let p = units::skid_buffer(8).tracker("none", 0, "1'b0");
        assert!(p.harness().unwrap_err().contains("tracker `none`: width 0"));
    }

    #[test]
    fn a_depth_given_overrides_every_check() {
        let sby = units::skid_buffer(8).sby(&["skid_buffer_w8.v".into()], Some(3), 60);
        assert_eq!(sby.matches(": depth 3\n").count(), 3, "{sby}");
        assert!(sby.contains("timeout 60\n"));
    }

    #[test]
    fn a_net_or_stream_the_module_lacks_is_refused() {
        let p = units::skid_buffer(8).invariant("bad", "dut.no_such_net == 1'b0");
        let e = p.harness().unwrap_err();
        assert!(
            e.contains("`dut.no_such_net`") && e.contains("no net `no_such_net`"),
            "{e}"
        );
        let p = Proof::new(crate::examples::skid_buffer(8), &["in"], &["result"], 4)
            .check(Check::Handshake, Mode::Bmc);
        let e = p.harness().unwrap_err();
        assert!(
            e.contains("stream `result`: the module has no port `result_valid`"),
            "{e}"
        );
        let mut p = units::skid_buffer(8);
        p.flows.push(Flow::Counted {
            name: "x".into(),
            input: "1'b1".into(),
            output: "dut.skid_nothing".into(),
            capacity: 1,
            occupancy: None,
        });
        let e = p.harness().unwrap_err();
        assert!(e.contains("no net `skid_nothing`"), "{e}");
    }
}
