//! Testbench pieces, generic over `Engine` (SpinalHDL-style small parts).

pub mod accounting;
pub mod bench;
pub mod driver;
pub mod monitor;
pub mod multi;
pub mod prng;
pub mod scoreboard;
pub mod stalls;
pub mod stop_rule;
pub mod stream;
pub mod trace_window;
pub mod watchdog;

pub use accounting::{Accounting, AccountingReport};
pub use bench::{
    run_stream_bench, run_stream_bench_with_progress, run_with_vcd_on_failure, BenchConfig,
    BenchReport, Progress, StreamNames, Vector,
};
pub use driver::StreamDriver;
pub use monitor::StreamMonitor;
pub use multi::{
    run_multi_stream_bench, run_multi_stream_bench_reactive, run_multi_stream_bench_traced,
    run_multi_stream_bench_watching, run_multi_with_vcd_on_failure, stream_seed, ActiveWindow,
    MultiReport, PulseCounts, PulseWatch, Reactor, StreamBeats,
};
pub use prng::Prng;
pub use scoreboard::{FieldDecoder, FieldDiff, Mismatch, Scoreboard};
pub use stalls::{StallGen, Stalls, StreamStalls};
pub use stop_rule::StopRule;
pub use stream::{StreamPorts, Transaction};
pub use trace_window::TraceWindow;
pub use watchdog::{dump_ports, Hang, Watchdog};
