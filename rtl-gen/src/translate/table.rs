//! The translation table (SPEC.md 7.5) in hardware: one valid bit per
//! entry in a register (reset: all invalid) and the entries `(L, tx, ty,
//! tz)` in a register file of the next power-of-two depth. One write port
//! (determine), asynchronous read ports (determine's read, apply). A read
//! of an invalid entry or an id past the depth returns valid = 0 and zeros,
//! so undefined memory words never reach an output.

use golden::translate::model::TranslateDesign;
use golden::translate::translation::trans_bits;

use crate::{Memory, Module, Signal};

/// What a read port returns.
pub(crate) struct Entry<'m> {
    pub valid: Signal<'m>,
    pub lod: Signal<'m>,
    /// Signed `D+1`-bit components.
    pub t: [Signal<'m>; 3],
}

pub(crate) struct Table<'m> {
    m: &'m Module,
    depth: u32,
    hier_bits: u32,
    lod_bits: u32,
    trans_bits: u32,
    valid: Signal<'m>,
    mem: Memory<'m>,
}

impl<'m> Table<'m> {
    pub(crate) fn new(m: &'m Module, d: &TranslateDesign) -> Table<'m> {
        let p = d.params();
        let depth = d.unit.table_depth;
        let tb = trans_bits(p);
        let words = depth.next_power_of_two().max(2);
        Table {
            m,
            depth,
            hier_bits: p.hier_bits as u32,
            lod_bits: p.lod_bits(),
            trans_bits: tb,
            valid: m.reg("table_valid", depth),
            mem: m.memory("table", p.lod_bits() + 3 * tb, words),
        }
    }

    /// One bit: `id >= depth`; `None` when every `H`-bit id is in range.
    pub(crate) fn id_out_of_range(&self, id: Signal<'m>) -> Option<Signal<'m>> {
        if u64::from(self.depth) == 1u64 << self.hier_bits {
            None
        } else {
            Some(id.ge(self.depth as u128))
        }
    }

    fn addr(&self, id: Signal<'m>) -> Signal<'m> {
        let ab = self.mem.addr_width();
        if ab == id.width() {
            id
        } else {
            id.slice(ab - 1, 0)
        }
    }

    /// Reads entry `id` (asynchronously: this cycle's table, before this
    /// edge's write).
    pub(crate) fn read(&self, id: Signal<'m>, name: &str) -> Entry<'m> {
        let options: Vec<Signal<'m>> = (0..1u32 << self.hier_bits)
            .map(|i| {
                if i < self.depth {
                    self.valid.bit(i)
                } else {
                    self.m.lit(0, 1)
                }
            })
            .collect();
        let valid = id.select(&options).name(&format!("{name}_valid"));
        let word = self.mem.read(self.addr(id));
        let word = valid
            .mux(word, self.m.lit(0, word.width()))
            .name(&format!("{name}_entry"));
        let (lb, tb) = (self.lod_bits, self.trans_bits);
        let comp = |i: u32| word.slice(lb + (i + 1) * tb - 1, lb + i * tb).as_signed();
        Entry {
            valid,
            lod: word.slice(lb - 1, 0),
            t: [comp(0), comp(1), comp(2)],
        }
    }

    /// The write port (call once): on the edge when `en`, entry `id`
    /// becomes valid with `(lod, t)`.
    pub(crate) fn write(
        &self,
        id: Signal<'m>,
        lod: Signal<'m>,
        t: [Signal<'m>; 3],
        en: Signal<'m>,
    ) {
        let word = self.m.concat(&[
            t[2].as_unsigned(),
            t[1].as_unsigned(),
            t[0].as_unsigned(),
            lod,
        ]);
        self.mem.write(self.addr(id), word, en);
        let one_hot = self.m.lit(1, self.depth) << id;
        self.valid.next(en.mux(self.valid | one_hot, self.valid));
    }
}
