//! LSD radix sort on integer keys and a branch-free Morton spread: the two
//! pieces that make the bottom-up build linear in the number of primitives.

/// Bits per radix digit: 2^11 counters (8 KiB) per pass stay in L1.
const DIGIT_BITS: u32 = 11;
const BUCKETS: usize = 1 << DIGIT_BITS;

/// Stable LSD radix sort of `items` by the low `key_bits` bits of `key`.
/// `scratch` is reused storage (its contents are discarded). Histograms of
/// all passes are taken in one read; a pass whose digit is the same for every
/// item is skipped, since it would not move anything.
pub fn radix_sort<T: Copy, K: SortKey>(
    items: &mut Vec<T>,
    scratch: &mut Vec<T>,
    key_bits: u32,
    key: impl Fn(&T) -> K,
) {
    let n = items.len();
    if n < 2 || key_bits == 0 {
        return;
    }
    let passes = sort_passes::<K>(key_bits);
    let mut hist = vec![[0u32; BUCKETS]; passes];
    // The common pass counts get a loop over a constant number of passes,
    // unrolled: the same counts.
    match passes {
        4 => histograms::<4, T, K>(items, &key, &mut hist),
        5 => histograms::<5, T, K>(items, &key, &mut hist),
        _ => {
            for it in items.iter() {
                let k = key(it);
                for (p, h) in hist.iter_mut().enumerate() {
                    h[k.digit(p)] += 1;
                }
            }
        }
    }
    let todo = moving_passes(&hist, n);
    passes_serial(items, scratch, &hist, &todo, &key);
}

/// Passes `todo` of the one-thread sort over `items`, in order (`hist`:
/// every pass's digit counts, which do not depend on the items' order),
/// each a scatter into `scratch`, which becomes the items.
fn passes_serial<T: Copy, K: SortKey>(
    items: &mut Vec<T>,
    scratch: &mut Vec<T>,
    hist: &[[u32; BUCKETS]],
    todo: &[usize],
    key: &impl Fn(&T) -> K,
) {
    let n = items.len();
    scratch.clear();
    scratch.reserve(n);
    for &p in todo {
        let mut offsets = [0u32; BUCKETS];
        let mut sum = 0u32;
        for (o, &c) in offsets.iter_mut().zip(hist[p].iter()) {
            *o = sum;
            sum += c;
        }
        // The scatter writes every slot of `scratch`'s first `n` once (the
        // offsets of the digits partition `0..n`), so it needs no copies
        // in it first.
        scratch.clear();
        let out = &mut scratch.spare_capacity_mut()[..n];
        for it in items.iter() {
            let d = key(it).digit(p);
            let o = offsets[d] as usize;
            debug_assert!(o < n);
            // SAFETY: `o` is below `n`: digit `d`'s offsets run from the
            // count of the smaller digits up to that plus `d`'s count.
            unsafe { out.get_unchecked_mut(o) }.write(*it);
            offsets[d] += 1;
        }
        // SAFETY: the scatter wrote each of the first `n` slots (above).
        unsafe { scratch.set_len(n) };
        std::mem::swap(items, scratch);
    }
}

/// The digit counts of `P` passes (`hist.len() == P`) in one read.
#[inline(always)]
fn histograms<const P: usize, T, K: SortKey>(
    items: &[T],
    key: &impl Fn(&T) -> K,
    hist: &mut [[u32; BUCKETS]],
) {
    let hist: &mut [[u32; BUCKETS]; P] = hist.try_into().expect("P passes");
    for it in items {
        let k = key(it);
        for (p, h) in hist.iter_mut().enumerate() {
            h[k.digit(p)] += 1;
        }
    }
}

/// The passes that sort by the low `key_bits` bits of keys `K`: bits above
/// `K::BITS` are zero, so no pass reads beyond them, and a digit's shift is
/// below `K::BITS` (which [`SortKey::digit`] may assume).
fn sort_passes<K: SortKey>(key_bits: u32) -> usize {
    key_bits.min(K::BITS).div_ceil(DIGIT_BITS) as usize
}

/// Below this many items the sorts run on one thread: the threads' setup
/// per pass costs more than it saves (on the generated building's 67,054
/// entries two threads sorted slower than one).
const PARALLEL_MIN: usize = 1 << 18;

/// A raw pointer the scatter threads share; each writes a disjoint set of
/// slots (its own block's items at offsets no other block is given).
#[derive(Clone, Copy)]
struct Slots<T>(*mut T);
// SAFETY: only used to write disjoint slots of one live buffer, below.
unsafe impl<T: Send> Send for Slots<T> {}
unsafe impl<T: Send> Sync for Slots<T> {}

impl<T> Slots<T> {
    /// Writes slot `i`.
    ///
    /// # Safety
    /// `i` is within the buffer's capacity and no other thread writes it.
    #[inline(always)]
    unsafe fn write(&self, i: usize, v: T) {
        self.0.add(i).write(v)
    }
}

/// [`radix_sort`] on the threads of the current rayon pool: the same order
/// (stable, by the same digits). The items are cut into one block per
/// thread; per pass, each block's histogram is taken in parallel, each
/// (block, digit) gets the offset where its run goes (digits in order, and
/// within a digit the blocks in order, which keeps the sort stable), and the
/// blocks scatter in parallel.
pub fn radix_sort_parallel<T: Copy + Send + Sync, K: SortKey>(
    items: &mut Vec<T>,
    scratch: &mut Vec<T>,
    key_bits: u32,
    key: impl Fn(&T) -> K + Sync,
) {
    use rayon::prelude::*;
    let n = items.len();
    let threads = rayon::current_num_threads();
    if n < PARALLEL_MIN || threads < 2 || key_bits == 0 {
        return radix_sort(items, scratch, key_bits, key);
    }
    let passes = sort_passes::<K>(key_bits);
    let total = items
        .par_chunks(n.div_ceil(threads))
        .map(|part| histograms_of(part, 0..passes, &key))
        .reduce_with(|mut a, b| {
            add_counts(&mut a, &b);
            a
        })
        .expect("n > 0");
    let todo = moving_passes(&total, n);
    passes_parallel(items, scratch, &todo, &key);
}

/// The items of `parts`, one after the other, sorted as [`radix_sort`]
/// sorts them. With enough items, on the threads of the current rayon pool,
/// and the first pass that moves anything scatters from the parts
/// themselves, so they are never copied into one vector first. With fewer,
/// the parts are copied into one vector and sorted on one thread: each
/// part's digit counts would cost more than the copy (measured on the
/// bunny's 15 parts).
pub fn radix_sort_parts<T: Copy + Send + Sync, K: SortKey>(
    mut parts: Vec<Vec<T>>,
    key_bits: u32,
    key: impl Fn(&T) -> K + Sync,
) -> Vec<T> {
    let mut out = Vec::new();
    let bufs = SortBuffers {
        out: &mut out,
        scratch: &mut Vec::new(),
        keep_parts: false,
    };
    radix_sort_parts_into(&mut parts, bufs, key_bits, key);
    out
}

/// Where [`radix_sort_parts_into`] sorts.
pub struct SortBuffers<'a, T> {
    /// Receives the sorted items (cleared first).
    pub out: &'a mut Vec<T>,
    /// The passes' second buffer.
    pub scratch: &'a mut Vec<T>,
    /// Keep the parts' vectors (emptied) for the next use; else they are
    /// freed as soon as they have been read, which lowers the peak.
    pub keep_parts: bool,
}

/// [`radix_sort_parts`] into kept buffers: the same order.
pub fn radix_sort_parts_into<T: Copy + Send + Sync, K: SortKey>(
    parts: &mut Vec<Vec<T>>,
    bufs: SortBuffers<'_, T>,
    key_bits: u32,
    key: impl Fn(&T) -> K + Sync,
) {
    use rayon::prelude::*;
    let SortBuffers {
        out,
        scratch,
        keep_parts,
    } = bufs;
    let release = |parts: &mut Vec<Vec<T>>| match keep_parts {
        true => parts.iter_mut().for_each(Vec::clear),
        false => *parts = Vec::new(),
    };
    let n: usize = parts.iter().map(Vec::len).sum();
    out.clear();
    out.reserve(n);
    if n < PARALLEL_MIN || rayon::current_num_threads() < 2 {
        for part in parts.iter() {
            out.extend_from_slice(part);
        }
        release(parts);
        return radix_sort(out, scratch, key_bits, key);
    }
    let passes = sort_passes::<K>(key_bits);
    let hists: Vec<Vec<[u32; BUCKETS]>> = parts
        .par_iter()
        .map(|part| histograms_of(part, 0..passes, &key))
        .collect();
    let mut total = vec![[0u32; BUCKETS]; passes];
    for h in &hists {
        add_counts(&mut total, h);
    }
    let todo = moving_passes(&total, n);
    let blocks: Vec<&[T]> = parts.iter().map(Vec::as_slice).collect();
    match todo.first() {
        Some(&p) => {
            let first: Vec<[u32; BUCKETS]> = hists.iter().map(|h| h[p]).collect();
            scatter(&blocks, &first, p, &key, out);
        }
        // No pass moves anything: the items are already in order.
        None => {
            for part in &blocks {
                out.extend_from_slice(part);
            }
        }
    }
    drop(blocks);
    release(parts);
    let rest = todo.get(1..).unwrap_or(&[]);
    passes_parallel(out, scratch, rest, &key);
}

/// The digit counts of `passes` over `part`, in one read.
fn histograms_of<T, K: SortKey>(
    part: &[T],
    passes: std::ops::Range<usize>,
    key: &impl Fn(&T) -> K,
) -> Vec<[u32; BUCKETS]> {
    let mut hist = vec![[0u32; BUCKETS]; passes.len()];
    for it in part {
        let k = key(it);
        for (h, p) in hist.iter_mut().zip(passes.clone()) {
            h[k.digit(p)] += 1;
        }
    }
    hist
}

/// The passes that move something: a pass whose digit is the same for
/// every one of the `n` items (`total`: each pass's counts) moves nothing.
fn moving_passes(total: &[[u32; BUCKETS]], n: usize) -> Vec<usize> {
    (0..total.len())
        .filter(|&p| !total[p].iter().any(|&c| c as usize == n))
        .collect()
}

/// Passes `todo` of the parallel sort over `items`, in order: per pass, one
/// block per thread, each block's counts, then the scatter into `scratch`,
/// which becomes the items.
fn passes_parallel<T: Copy + Send + Sync, K: SortKey>(
    items: &mut Vec<T>,
    scratch: &mut Vec<T>,
    todo: &[usize],
    key: &(impl Fn(&T) -> K + Sync),
) {
    use rayon::prelude::*;
    let block = items.len().div_ceil(rayon::current_num_threads()).max(1);
    for &p in todo {
        let blocks: Vec<&[T]> = items.chunks(block).collect();
        let hists: Vec<[u32; BUCKETS]> = blocks
            .par_iter()
            .map(|part| histograms_of(part, p..p + 1, key)[0])
            .collect();
        scatter(&blocks, &hists, p, key, scratch);
        std::mem::swap(items, scratch);
    }
}

/// One pass: the items of `blocks` (in order; `hists[b]`: block `b`'s
/// counts of digit `p`) stably scattered by digit `p` into `out` (cleared
/// first), the blocks in parallel.
fn scatter<T: Copy + Send + Sync, K: SortKey>(
    blocks: &[&[T]],
    hists: &[[u32; BUCKETS]],
    p: usize,
    key: &(impl Fn(&T) -> K + Sync),
    out: &mut Vec<T>,
) {
    use rayon::prelude::*;
    let n: usize = blocks.iter().map(|b| b.len()).sum();
    let mut offsets = vec![[0u32; BUCKETS]; hists.len()];
    let mut sum = 0u32;
    for d in 0..BUCKETS {
        for (o, h) in offsets.iter_mut().zip(hists) {
            o[d] = sum;
            sum += h[d];
        }
    }
    out.clear();
    out.reserve(n);
    let slots = Slots(out.as_mut_ptr());
    let block = |(part, off): (&&[T], &mut [u32; BUCKETS])| {
        for it in part.iter() {
            let d = key(it).digit(p);
            // SAFETY: the offsets of (block, d) run over slots no other
            // (block, digit) pair is given, all below n, within out's
            // capacity; each block writes only its own.
            unsafe { slots.write(off[d] as usize, *it) };
            off[d] += 1;
        }
    };
    blocks
        .par_iter()
        .zip(offsets.par_iter_mut())
        .for_each(block);
    // SAFETY: the scatter wrote each of the n slots once (the offsets of
    // all (block, digit) pairs partition 0..n).
    unsafe { out.set_len(n) };
}

/// Adds the digit counts `b` into `a`, pass by pass.
fn add_counts(a: &mut [[u32; BUCKETS]], b: &[[u32; BUCKETS]]) {
    for (ha, hb) in a.iter_mut().zip(b) {
        for (x, y) in ha.iter_mut().zip(hb) {
            *x += y;
        }
    }
}

/// An integer the sort takes its digits from. The leaf keys are `u64`
/// when they fit: a shift of a `u128` by a variable amount costs several
/// instructions and a branch on baseline x86-64, and the sort takes two
/// digits of every item per pass.
pub trait SortKey: Copy {
    /// The key's width in bits.
    const BITS: u32;
    /// Digit `pass` (bits `pass * DIGIT_BITS ..`) of the key; the sort asks
    /// only for digits starting below [`Self::BITS`] (see `sort_passes`).
    fn digit(self, pass: usize) -> usize;
}

impl SortKey for u128 {
    const BITS: u32 = 128;
    #[inline(always)]
    fn digit(self, pass: usize) -> usize {
        ((self >> (pass as u32 * DIGIT_BITS)) as usize) & (BUCKETS - 1)
    }
}

impl SortKey for u64 {
    const BITS: u32 = 64;
    /// The same digit as the `u128` of the same value.
    #[inline(always)]
    fn digit(self, pass: usize) -> usize {
        let shift = pass as u32 * DIGIT_BITS;
        debug_assert!(shift < 64);
        ((self >> shift) as usize) & (BUCKETS - 1)
    }
}

/// Spreads the low 21 bits of `v` so that bit `i` lands at bit `3i`.
#[inline(always)]
fn spread21(v: u64) -> u64 {
    let mut x = v & 0x1f_ffff;
    x = (x | x << 32) & 0x001f_0000_0000_ffff;
    x = (x | x << 16) & 0x001f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// The same code as [`crate::grid::morton3`], computed with masks instead of
/// a bit loop (the builder computes one per primitive and voxel).
#[inline(always)]
pub fn morton3_fast(x: u32, y: u32, z: u32) -> u128 {
    let s = |v: u32| spread21(v as u64) as u128 | (spread21((v >> 21) as u64) as u128) << 63;
    s(x) | s(y) << 1 | s(z) << 2
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::morton3;

    #[test]
    fn fast_morton_matches_the_grid_definition() {
        let mut s = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..10_000 {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let (x, y, z) = (s as u32 >> 1, (s >> 21) as u32 >> 1, (s >> 40) as u32 >> 1);
            assert_eq!(morton3_fast(x, y, z), morton3(x, y, z), "{x} {y} {z}");
        }
        let m = (1u32 << 31) - 1;
        assert_eq!(morton3_fast(m, m, m), morton3(m, m, m));
        assert_eq!(morton3_fast(m, 0, 0), morton3(m, 0, 0));
    }

    #[test]
    fn sorts_stably_by_key() {
        let mut s = 12345u64;
        let mut v: Vec<(u128, usize)> = (0..5000)
            .map(|i| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((((s >> 20) as u128) % 300) | ((s as u128 & 3) << 90), i)
            })
            .collect();
        let mut expect = v.clone();
        expect.sort_by_key(|e| e.0); // std's sort is stable
        let mut scratch = Vec::new();
        radix_sort(&mut v, &mut scratch, 92, |e| e.0);
        assert_eq!(v, expect);
    }

    /// Sorting from parts gives the sequential sort of their items one
    /// after the other: several parts, an empty one, every pass moving or
    /// none (all keys equal), and fewer items than the parallel minimum.
    #[test]
    fn sorting_parts_is_the_sequential_sort() {
        let mut s = 7u64;
        let mut item = |i: usize, spread: u128| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (((s >> 20) as u128 % spread) | ((s as u128 & 1) << 50), i)
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        for (n, spread, same) in [
            (3 * PARALLEL_MIN + 5, 4000, false),
            (3 * PARALLEL_MIN, 1, true),
            (100, 50, false),
        ] {
            let all: Vec<(u128, usize)> = (0..n)
                .map(|i| if same { (9, i) } else { item(i, spread) })
                .collect();
            let cuts = [0, n / 5, n / 5, n / 2, n];
            let parts: Vec<Vec<(u128, usize)>> =
                cuts.windows(2).map(|w| all[w[0]..w[1]].to_vec()).collect();
            let mut expect = all.clone();
            expect.sort_by_key(|e| e.0);
            let got = pool.install(|| radix_sort_parts(parts, 52, |e| e.0));
            assert_eq!(got, expect, "{n} items");
        }
    }

    #[test]
    fn parallel_sort_is_the_sequential_sort() {
        let mut s = 99u64;
        let v: Vec<(u128, usize)> = (0..3 * PARALLEL_MIN + 17)
            .map(|i| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((((s >> 20) as u128) % 5000) | ((s as u128 & 3) << 60), i)
            })
            .collect();
        let mut expect = v.clone();
        expect.sort_by_key(|e| e.0);
        for threads in [2, 3] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut got = v.clone();
            pool.install(|| radix_sort_parallel(&mut got, &mut Vec::new(), 62, |e| e.0));
            assert_eq!(got, expect, "{threads} threads");
        }
    }
}
