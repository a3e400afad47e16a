//! The exported testbench's store model on a shared store port (the
//! merger with `StorePort::Shared`, SPEC 8.15 and 9.1): the port's reads
//! come in an order that depends on timing, so the testbench answers each
//! `store_req` beat as it comes, from a `$readmemh` store image, in order
//! on `store_resp` `latency` clocks later at the earliest, as cosim's
//! `StoreModel` does.
//!
//! The image holds, per merge, the words golden's units read: per merge,
//! array and hierarchy a run of words (`base`, `len`) indexed by the read's
//! `index`, holes zero. A read outside its merge's runs is a failure, and
//! each merge must make as many reads as golden's units (checked at the
//! end). A read's merge is the one in flight (its `cfg` beat sent, its
//! `header` beat not yet taken: two at most) whose number mod 2 is the
//! read's `slot`; a slot naming none is a failure.

use std::fmt::Write as _;

use golden::bits::Bits;

use golden::layout::Field;

/// The store a testbench answers a shared port's reads from.
#[derive(Clone, Debug)]
pub struct StoreSpec {
    /// Clocks from a read taken to its answer, at the earliest (`1..`).
    pub latency: u64,
    /// The input stream whose beats start the merges (`cfg`), numbered
    /// from 0.
    pub epoch_input: String,
    /// The output stream whose beats end them (`header`).
    pub epoch_output: String,
    /// `store_req`'s fields.
    pub index: Field,
    /// See `index`.
    pub hier: Field,
    /// See `index`: the read's merge's number mod 2.
    pub slot: Field,
    /// See `index`.
    pub array: Field,
    /// Per merge, array (node 0, reference 1) and hierarchy (`2^H` of
    /// them), at `(merge * 2 + array) * 2^H + hier`: the first word of its
    /// run in `words` and the run's length.
    pub runs: Vec<(u32, u32)>,
    /// The words, each `store_resp`'s width.
    pub words: Vec<Bits>,
    /// Per merge, the reads golden's units make.
    pub reads: Vec<u64>,
}

impl StoreSpec {
    /// Merges.
    pub fn merges(&self) -> usize {
        self.reads.len()
    }

    /// Hierarchies per merge and array (`2^H`).
    pub fn hierarchies(&self) -> u64 {
        1 << self.hier.width
    }
}

/// Reads in flight the testbench holds (the largest tag FIFO, `2^8`).
pub(super) const QUEUE: usize = 256;

/// The testbench's pieces of the store model.
pub(super) struct StoreParts {
    pub decls: String,
    pub load: String,
    pub drive: String,
    pub observe: String,
    pub done: String,
    pub end: String,
}

/// `reg[k:0]`: `reg` as an index into `n` entries.
fn ix(reg: &str, n: usize) -> String {
    format!("{reg}[{}:0]", super::verilog::index_bits(n) - 1)
}

/// `data[hi:lo]` of field `f` of `port`, zero-extended to 32 bits.
fn field32(port: &str, f: &Field) -> String {
    let bits = match f.width {
        1 => format!("{port}[{}]", f.offset),
        w => format!("{port}[{}:{}]", f.offset + w - 1, f.offset),
    };
    match f.width {
        32 => bits,
        w => format!("{{{}'d0, {bits}}}", 32 - w),
    }
}

/// The pieces for store `st` with `store_resp` `resp_width` bits wide and
/// masks of `mask_words` words; `word` indexes a mask by the cycle.
pub(super) fn parts(st: &StoreSpec, resp_width: u32, mask_words: usize, word: &str) -> StoreParts {
    let (m, n) = (st.merges().max(1), st.words.len().max(1));
    let runs = st.runs.len().max(1);
    let w = resp_width - 1;
    let hc = st.hierarchies();
    let decls = format!(
        r#"
    // The store on the shared port: each `store_req` beat answered from the
    // store image golden's units read (per merge, array and hierarchy a run
    // of words), in order on `store_resp`, {lat} clock(s) later at the
    // earliest; `store_req`'s ready and `store_resp`'s valid follow masks.
    localparam [31:0] tb_store_latency = 32'd{lat};
    localparam [31:0] tb_store_merges = 32'd{merges};
    reg [{w}:0] tb_store_words [0:{nw}];
    reg [31:0] tb_store_base [0:{nr}];
    reg [31:0] tb_store_len [0:{nr}];
    reg [31:0] tb_store_expect [0:{nm}];
    reg [31:0] tb_store_reads [0:{nm}];
    reg [63:0] tb_store_req_ready [0:{mw}];
    reg [63:0] tb_store_resp_go [0:{mw}];
    reg [{w}:0] tb_store_q [0:{q}];
    reg [31:0] tb_store_due [0:{q}];
    reg [31:0] tb_store_head = 32'd0;
    reg [31:0] tb_store_tail = 32'd0;
    reg [31:0] tb_store_e = 32'd0;
    reg [31:0] tb_store_i = 32'd0;
    reg [31:0] tb_store_t = 32'd0;
    reg [31:0] tb_store_w = 32'd0;
    reg [31:0] tb_store_k = 32'd0;
    reg tb_store_answered = 1'b0;
"#,
        lat = st.latency.max(1),
        merges = st.merges(),
        nw = n - 1,
        nr = runs - 1,
        nm = m - 1,
        mw = mask_words - 1,
        q = QUEUE - 1,
    );
    let mut load = String::new();
    for what in ["words", "base", "len", "expect", "req_ready", "resp_go"] {
        let _ = writeln!(
            load,
            "        $readmemh(\"{}\", tb_store_{what});",
            super::vector_file("store", what)
        );
    }
    let _ = writeln!(
        load,
        "        for (tb_store_k = 32'd0; tb_store_k < 32'd{m}; tb_store_k = tb_store_k + 32'd1) tb_store_reads[{k}] = 32'd0;",
        k = ix("tb_store_k", m)
    );
    let at = format!("tb_store_head[{}:0]", QUEUE.ilog2() - 1);
    let drive = format!(
        r#"            // The store: `store_req`'s ready from its mask; the next answer
            // due goes out on `store_resp` when its mask lets it, held until taken.
            store_req_ready = tb_store_req_ready[{word}][tb_cycle[5:0]];
            if (tb_store_answered) begin
                tb_store_answered = 1'b0;
                store_resp_valid = 1'b0;
            end
            if (!store_resp_valid && tb_store_head != tb_store_tail
                    && tb_store_due[{at}] <= tb_cycle && tb_store_resp_go[{word}][tb_cycle[5:0]]) begin
                store_resp_valid = 1'b1;
                store_resp_data = tb_store_q[{at}];
            end
"#
    );
    let tail = format!("tb_store_tail[{}:0]", QUEUE.ilog2() - 1);
    let (e, o) = (&st.epoch_input, &st.epoch_output);
    let observe = format!(
        r#"            if (store_resp_valid && store_resp_ready) begin
                tb_store_answered = 1'b1;
                tb_store_head = tb_store_head + 32'd1;
                tb_moved = 1'b1;
            end
            if (store_req_valid && store_req_ready) begin
                tb_moved = 1'b1;
                // The merge in flight whose number mod 2 is the slot: the
                // newest taken, or the one before it.
                tb_store_e = tb_{e}_sent - 32'd1;
                if (tb_store_e[0] != store_req_data[{slot_bit}]) tb_store_e = tb_store_e - 32'd1;
                tb_store_i = {index};
                tb_store_t = (tb_store_e * 32'd2 + {array}) * 32'd{hc} + {hier};
                tb_store_w = 32'd0;
                if (tb_{e}_sent == 32'd0 || tb_store_e > tb_{e}_sent || tb_store_e < tb_{o}_got) begin
                    $display("FAIL: cycle %0d: `store_req` read of array %0d hierarchy %0d index %0d with slot %0d: no merge of that slot in flight (merges %0d..%0d)", tb_cycle, {array}, {hier}, tb_store_i, {slot}, tb_{o}_got, tb_{e}_sent - 32'd1);
                    tb_failed = 1'b1;
                end else if (tb_store_e >= tb_store_merges || tb_store_t >= 32'd{runs}
                        || tb_store_i >= tb_store_len[{t}]) begin
                    $display("FAIL: cycle %0d: `store_req` read of array %0d hierarchy %0d index %0d in merge %0d: outside the words golden's units read", tb_cycle, {array}, {hier}, tb_store_i, tb_store_e);
                    tb_failed = 1'b1;
                end else if (tb_store_tail - tb_store_head == 32'd{queue}) begin
                    $display("FAIL: cycle %0d: more than {queue} `store_req` reads unanswered", tb_cycle);
                    tb_failed = 1'b1;
                end else begin
                    tb_store_w = tb_store_base[{t}] + tb_store_i;
                end
                if (tb_store_w >= 32'd{n}) begin
                    $display("FAIL: cycle %0d: store run past the image's {n} words", tb_cycle);
                    tb_failed = 1'b1;
                end else if (!tb_failed) begin
                    tb_store_q[{tail}] = tb_store_words[{w}];
                    tb_store_due[{tail}] = tb_cycle + tb_store_latency;
                    tb_store_tail = tb_store_tail + 32'd1;
                    tb_store_reads[{e_at}] = tb_store_reads[{e_at}] + 32'd1;
                end
            end
"#,
        index = field32("store_req_data", &st.index),
        hier = field32("store_req_data", &st.hier),
        slot = field32("store_req_data", &st.slot),
        slot_bit = st.slot.offset,
        array = field32("store_req_data", &st.array),
        queue = QUEUE,
        t = ix("tb_store_t", runs),
        runs = runs,
        n = n,
        w = ix("tb_store_w", n),
        e_at = ix("tb_store_e", m),
    );
    let end = format!(
        r#"        for (tb_store_k = 32'd0; tb_store_k < 32'd{merges}; tb_store_k = tb_store_k + 32'd1) begin
            if (!tb_failed && tb_store_reads[{k}] != tb_store_expect[{k}]) begin
                $display("FAIL: merge %0d made %0d `store_req` reads; golden's units make %0d", tb_store_k, tb_store_reads[{k}], tb_store_expect[{k}]);
                tb_failed = 1'b1;
            end
        end
"#,
        merges = st.merges(),
        k = ix("tb_store_k", m),
    );
    StoreParts {
        decls,
        load,
        drive,
        observe,
        done: "tb_store_head == tb_store_tail && !store_resp_valid".into(),
        end,
    }
}
