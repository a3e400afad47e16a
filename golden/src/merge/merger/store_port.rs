//! The merger's store front end (SPEC.md section 8.15, "The shared store
//! port"): `n` read streams, each of one array of the store (a node array
//! read answers a node record, a reference array read a reference),
//! arbitrated round robin onto one read request stream `store_req`, whose
//! in-order answers on `store_resp` go back to the requester that asked.
//!
//! The beat layouts are defined here once; the RTL
//! (`rtl_gen::merge::store_port_unit`) and the benches read them. The
//! transaction model: every requester gets, in its own request order, the
//! store's word at each index it asked for; the interleaving on `store_req`
//! depends on timing (round robin among the requesters showing a request
//! that cycle), so it is no part of the transaction.

use std::collections::HashMap;

use crate::bits::Bits;
use crate::layout::{Field, Layout};
use crate::merge::fetcher::FetchLayout;
use crate::params::Params;
use crate::store::Hierarchy;

/// How the merger's units reach the store (SPEC 8.15).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum StorePort {
    /// Every fetcher and the writer with its own read streams, passed out of
    /// the top (the memory system arbitrates outside).
    #[default]
    PerUnit,
    /// One read port (`store_req` / `store_resp`) for every unit, its front
    /// end in the top, with a tag FIFO of `2^tag_bits` reads in flight.
    Shared {
        /// The tag FIFO holds `2^tag_bits` reads (`1..=8`).
        tag_bits: u32,
    },
}

impl StorePort {
    /// The shared port's default tag FIFO: 8 reads in flight, enough for a
    /// store answering 6 clocks after the request at one read per clock.
    pub const SHARED: StorePort = StorePort::Shared { tag_bits: 3 };
}

/// Which array of the store a read is of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum StoreArray {
    /// The node array: a read answers a node record.
    Node,
    /// The reference array: a read answers a reference.
    Reference,
}

impl StoreArray {
    /// The value of `store_req`'s `array` bit.
    pub fn code(self) -> u64 {
        match self {
            StoreArray::Node => 0,
            StoreArray::Reference => 1,
        }
    }

    /// The array of `store_req`'s `array` bit `code`.
    pub fn of_code(code: u64) -> StoreArray {
        if code == 0 {
            StoreArray::Node
        } else {
            StoreArray::Reference
        }
    }

    /// The letter of the array in module names (`n`, `r`).
    pub fn letter(self) -> char {
        match self {
            StoreArray::Node => 'n',
            StoreArray::Reference => 'r',
        }
    }
}

/// The store port's beats for grid parameters `p`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StorePortLayout {
    /// A requester's request: `index`, `hier`, `slot` (`I + H + 1` bits).
    pub addr: Layout,
    /// A `store_req` beat: a request's fields, then `array` (`I + H + 2`).
    pub req: Layout,
    /// `store_req` (and a requester's request): `index` (I bits) from bit 0.
    pub index: Field,
    /// `store_req` (and a requester's request): `hier` (H bits) above
    /// `index`, the hierarchy whose array is read (a fetcher reads its
    /// input's, the writer names it in its request).
    pub hier: Field,
    /// `store_req` (and a requester's request): `slot` (1 bit) above
    /// `hier`, the merge the read is for: its sequence number since reset,
    /// mod 2. Two merges may read at once (the older's writer, the newer's
    /// fetchers: SPEC 8.15, "Consecutive merges overlap"), and this bit is
    /// what tells the store whose read each is.
    pub slot: Field,
    /// `store_req`: `array` (1 bit, [`StoreArray::code`]) above `slot`.
    pub array: Field,
    /// Width of a node record (a node read's answer).
    pub node_width: u32,
    /// Width of a reference (a reference read's answer).
    pub ref_width: u32,
    /// Width of a `store_resp` beat: the wider answer; a narrower answer
    /// sits in the low bits, the rest zero.
    pub resp_width: u32,
}

impl StorePortLayout {
    /// The layout for `p` (the record and reference widths of the fetchers,
    /// 8.13).
    pub fn new(p: &Params) -> StorePortLayout {
        let fl = FetchLayout::new(p);
        let (node_width, ref_width) = (fl.node.width(), fl.reference.width());
        let mut addr = Layout::new("store request address");
        let index = addr.push("index", fl.index_width);
        let hier = addr.push("hier", p.hier_bits as u32);
        let slot = addr.push("slot", 1);
        let mut req = addr.clone();
        let array = req.push("array", 1);
        StorePortLayout {
            addr,
            req,
            index,
            hier,
            slot,
            array,
            node_width,
            ref_width,
            resp_width: node_width.max(ref_width),
        }
    }

    /// The answer width of a read of `array`.
    pub fn width_of(&self, array: StoreArray) -> u32 {
        match array {
            StoreArray::Node => self.node_width,
            StoreArray::Reference => self.ref_width,
        }
    }

    /// The `store_req` beat of a read `r`.
    pub fn pack_req(&self, r: StoreRead) -> Result<Bits, String> {
        let mut b = self.req.zero();
        b.set(&self.index, r.at.index).map_err(|e| e.to_string())?;
        b.set(&self.hier, r.at.hier).map_err(|e| e.to_string())?;
        b.set(&self.slot, r.slot).map_err(|e| e.to_string())?;
        b.set(&self.array, r.array.code())
            .map_err(|e| e.to_string())?;
        Ok(b)
    }

    /// The read a `store_req` beat asks for.
    pub fn unpack_req(&self, beat: &Bits) -> Result<StoreRead, String> {
        let get = |f: &Field| beat.get(f).map_err(|e| e.to_string());
        Ok(StoreRead {
            array: StoreArray::of_code(get(&self.array)?),
            slot: get(&self.slot)?,
            at: StoreAddr {
                hier: get(&self.hier)?,
                index: get(&self.index)?,
            },
        })
    }

    /// A requester's request (`r{j}_req`, [`Self::addr`]) for
    /// `at` in the merge of slot `slot`, as a number.
    pub fn addr_word(&self, slot: u64, at: StoreAddr) -> u64 {
        (slot << self.slot.offset) | (at.hier << self.hier.offset) | at.index
    }

    /// The `store_resp` beat carrying `word` (an answer of at most
    /// [`Self::resp_width`] bits, zero above its width).
    pub fn pack_resp(&self, word: &Bits) -> Result<Bits, String> {
        let mut b = Bits::zero(self.resp_width);
        b.put(0, word).map_err(|e| e.to_string())?;
        Ok(b)
    }
}

/// One `store_req` beat: a read of `array` at `at`, for the merge of slot
/// `slot` ([`StorePortLayout::slot`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct StoreRead {
    /// The array read.
    pub array: StoreArray,
    /// The merge's sequence number mod 2.
    pub slot: u64,
    /// Where.
    pub at: StoreAddr,
}

/// Where a read goes: entry `index` of hierarchy `hier`'s array.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct StoreAddr {
    /// The hierarchy.
    pub hier: u64,
    /// The entry of its array.
    pub index: u64,
}

/// The store's contents as the port reads them: packed words by array and
/// address.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct StoreWords {
    words: HashMap<(StoreArray, StoreAddr), Bits>,
}

impl StoreWords {
    /// Puts `word` at `a` of `array` (the first word put there stays).
    pub fn insert(&mut self, array: StoreArray, a: StoreAddr, word: Bits) {
        self.words.entry((array, a)).or_insert(word);
    }

    /// The word at `a` of `array`, if the store holds it.
    pub fn word(&self, array: StoreArray, a: StoreAddr) -> Option<&Bits> {
        self.words.get(&(array, a))
    }

    /// Words held.
    pub fn len(&self) -> usize {
        self.words.len()
    }

    /// Whether it holds no word.
    pub fn is_empty(&self) -> bool {
        self.words.is_empty()
    }

    /// Every word held, with its array and address, in no order.
    pub fn iter(&self) -> impl Iterator<Item = (StoreArray, StoreAddr, &Bits)> + '_ {
        self.words.iter().map(|((a, at), w)| (*a, *at, w))
    }

    /// The store image of `hs` as the merger's units read it: each
    /// hierarchy's node records in the node array and its references in
    /// the reference array, at (its id, the entry's index), packed with its
    /// parameters' node and reference layouts (the fetchers' and the
    /// writer's answers, 8.13).
    pub fn of_hierarchies<'a>(
        hs: impl IntoIterator<Item = &'a Hierarchy>,
    ) -> Result<StoreWords, String> {
        let mut store = StoreWords::default();
        for h in hs {
            let hier = h.id as u64;
            let err = |what: &str, e: crate::layout::LayoutError| {
                format!("hierarchy {}: packing its {what}: {e}", h.id)
            };
            let nodes = h.pack_nodes().map_err(|e| err("node records", e))?;
            let refs = h.pack_refs().map_err(|e| err("references", e))?;
            for (array, words) in [(StoreArray::Node, nodes), (StoreArray::Reference, refs)] {
                for (index, word) in words.into_iter().enumerate() {
                    let at = StoreAddr {
                        hier,
                        index: index as u64,
                    };
                    store.insert(array, at, word);
                }
            }
        }
        Ok(store)
    }
}

/// One run of the store port: per requester, its reads and the answers it
/// gets, in its order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StorePortTransaction {
    /// Per requester: the addresses it reads, in order.
    pub requests: Vec<Vec<StoreAddr>>,
    /// Per requester: the words it gets back, in order.
    pub responses: Vec<Vec<Bits>>,
}

/// The transaction of requesters of `arrays` reading `requests` (per
/// requester, in order) from `store`; an error names the requester and the
/// read the store does not hold.
pub fn store_port_transaction(
    arrays: &[StoreArray],
    requests: Vec<Vec<StoreAddr>>,
    store: &StoreWords,
) -> Result<StorePortTransaction, String> {
    if arrays.len() != requests.len() {
        return Err(format!(
            "{} request lists for {} requesters",
            requests.len(),
            arrays.len()
        ));
    }
    let mut responses = Vec::with_capacity(arrays.len());
    for (j, (a, reqs)) in arrays.iter().zip(&requests).enumerate() {
        let words = reqs
            .iter()
            .map(|&r| {
                store.word(*a, r).cloned().ok_or_else(|| {
                    format!(
                        "requester {j}: hierarchy {} index {} outside the {a:?} array",
                        r.hier, r.index
                    )
                })
            })
            .collect::<Result<Vec<_>, String>>()?;
        responses.push(words);
    }
    Ok(StorePortTransaction {
        requests,
        responses,
    })
}

/// The round-robin rule: after a grant to requester `last`, the next grant
/// goes to the first requester after `last` (in index order, wrapping
/// round) that shows a request; None when none does. So a requester that
/// keeps its request up waits for at most `n - 1` other grants.
pub fn round_robin_next(last: usize, requesting: &[bool]) -> Option<usize> {
    let n = requesting.len();
    (1..=n).map(|o| (last + o) % n).find(|&j| requesting[j])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_robin_serves_every_requester_in_turn() {
        let all = [true; 4];
        let mut last = 3;
        let mut order = Vec::new();
        for _ in 0..8 {
            last = round_robin_next(last, &all).unwrap();
            order.push(last);
        }
        assert_eq!(order, [0, 1, 2, 3, 0, 1, 2, 3]);
        assert_eq!(round_robin_next(1, &[true, false, false, false]), Some(0));
        assert_eq!(round_robin_next(0, &[false; 3]), None);
    }

    #[test]
    fn requests_pack_and_answers_route() {
        let l = StorePortLayout::new(&Params::default());
        let at = |hier, index| StoreAddr { hier, index };
        let read = StoreRead {
            array: StoreArray::Reference,
            slot: 1,
            at: at(3, 77),
        };
        let b = l.pack_req(read).unwrap();
        assert_eq!(l.unpack_req(&b).unwrap(), read);
        assert_eq!(b.get(&l.slot).unwrap(), 1);
        assert_eq!(l.addr_word(1, at(3, 77)) >> l.slot.offset, 1);
        assert!(l.resp_width >= l.node_width && l.resp_width >= l.ref_width);
        let mut store = StoreWords::default();
        for v in 0..4u64 {
            let node = Bits::from_words(&[v + 10], l.node_width).unwrap();
            store.insert(StoreArray::Node, at(1, v), node);
            let r = Bits::from_words(&[v], l.ref_width).unwrap();
            store.insert(StoreArray::Reference, at(2, v), r);
        }
        let arrays = [StoreArray::Node, StoreArray::Reference];
        let reqs = vec![vec![at(1, 3), at(1, 0)], vec![at(2, 2)]];
        let tx = store_port_transaction(&arrays, reqs, &store).unwrap();
        assert_eq!(
            &tx.responses[0][0],
            store.word(StoreArray::Node, at(1, 3)).unwrap()
        );
        assert_eq!(
            &tx.responses[1][0],
            store.word(StoreArray::Reference, at(2, 2)).unwrap()
        );
        let e = store_port_transaction(&arrays, vec![vec![at(2, 1)], vec![]], &store).unwrap_err();
        assert!(
            e.contains("requester 0") && e.contains("hierarchy 2 index 1"),
            "{e}"
        );
    }
}
