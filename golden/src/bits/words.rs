//! Arithmetic on little-endian `u64` word slices of a given bit width.
//!
//! These are the kernels shared by [`super::Bits`] and the DSL simulator. Every
//! function keeps the invariant that bits at and above `width` in the last
//! word are zero, so equality is plain word equality.

/// Number of 64-bit words needed for `width` bits (at least one).
pub fn words_for(width: u32) -> usize {
    (width as usize).div_ceil(64).max(1)
}

/// Mask of the valid bits in the last word of a `width`-bit value.
pub fn top_mask(width: u32) -> u64 {
    match width % 64 {
        0 => u64::MAX,
        r => (1u64 << r) - 1,
    }
}

/// Clears the bits at and above `width`.
pub fn clamp(dst: &mut [u64], width: u32) {
    let n = words_for(width);
    if width == 0 {
        dst.iter_mut().for_each(|w| *w = 0);
        return;
    }
    dst[n - 1] &= top_mask(width);
    for w in dst[n..].iter_mut() {
        *w = 0;
    }
}

/// Bit `i` of `a`.
pub fn get_bit(a: &[u64], i: u32) -> bool {
    (a[(i / 64) as usize] >> (i % 64)) & 1 == 1
}

/// Sets bit `i` of `a` to `v`.
pub fn set_bit(a: &mut [u64], i: u32, v: bool) {
    let w = &mut a[(i / 64) as usize];
    if v {
        *w |= 1 << (i % 64);
    } else {
        *w &= !(1 << (i % 64));
    }
}

/// `dst = a + b` modulo `2^width`; all operands `width` bits.
pub fn add(dst: &mut [u64], a: &[u64], b: &[u64], width: u32) {
    let mut carry = 0u64;
    for i in 0..words_for(width) {
        let (s1, c1) = a[i].overflowing_add(b[i]);
        let (s2, c2) = s1.overflowing_add(carry);
        dst[i] = s2;
        carry = (c1 as u64) + (c2 as u64);
    }
    clamp(dst, width);
}

/// `dst = a - b` modulo `2^width`.
pub fn sub(dst: &mut [u64], a: &[u64], b: &[u64], width: u32) {
    let mut borrow = 0u64;
    for i in 0..words_for(width) {
        let (d1, b1) = a[i].overflowing_sub(b[i]);
        let (d2, b2) = d1.overflowing_sub(borrow);
        dst[i] = d2;
        borrow = (b1 as u64) + (b2 as u64);
    }
    clamp(dst, width);
}

/// `dst = !a` within `width` bits.
pub fn not(dst: &mut [u64], a: &[u64], width: u32) {
    for i in 0..words_for(width) {
        dst[i] = !a[i];
    }
    clamp(dst, width);
}

/// Bitwise binary operation selected by `f`.
pub fn bitwise(dst: &mut [u64], a: &[u64], b: &[u64], width: u32, f: fn(u64, u64) -> u64) {
    for i in 0..words_for(width) {
        dst[i] = f(a[i], b[i]);
    }
    clamp(dst, width);
}

/// Unsigned comparison: `Less`, `Equal` or `Greater`.
pub fn cmp_unsigned(a: &[u64], b: &[u64], width: u32) -> std::cmp::Ordering {
    for i in (0..words_for(width)).rev() {
        match a[i].cmp(&b[i]) {
            std::cmp::Ordering::Equal => continue,
            o => return o,
        }
    }
    std::cmp::Ordering::Equal
}

/// Two's-complement signed comparison of two `width`-bit values.
pub fn cmp_signed(a: &[u64], b: &[u64], width: u32) -> std::cmp::Ordering {
    let sa = get_bit(a, width - 1);
    let sb = get_bit(b, width - 1);
    match (sa, sb) {
        (true, false) => std::cmp::Ordering::Less,
        (false, true) => std::cmp::Ordering::Greater,
        // Same sign: two's complement orders like unsigned.
        _ => cmp_unsigned(a, b, width),
    }
}

/// `dst = a << amount` within `width` bits (zero fill; `amount >= width` gives 0).
pub fn shl(dst: &mut [u64], a: &[u64], amount: u64, width: u32) {
    let n = words_for(width);
    if amount >= width as u64 {
        dst[..n].iter_mut().for_each(|w| *w = 0);
        return;
    }
    let ws = (amount / 64) as usize;
    let bs = (amount % 64) as u32;
    for i in (0..n).rev() {
        let lo = if i >= ws { a[i - ws] } else { 0 };
        let lower = if i > ws { a[i - ws - 1] } else { 0 };
        dst[i] = if bs == 0 {
            lo
        } else {
            (lo << bs) | (lower >> (64 - bs))
        };
    }
    clamp(dst, width);
}

/// `dst = a >> amount` within `width` bits; `arith` fills with bit `width-1`.
pub fn shr(dst: &mut [u64], a: &[u64], amount: u64, width: u32, arith: bool) {
    let n = words_for(width);
    let fill = arith && get_bit(a, width - 1);
    if amount >= width as u64 {
        let v = if fill { u64::MAX } else { 0 };
        dst[..n].iter_mut().for_each(|w| *w = v);
        clamp(dst, width);
        return;
    }
    // Logical shift first, then set the vacated top `amount` bits when filling.
    let ws = (amount / 64) as usize;
    let bs = (amount % 64) as u32;
    for (i, d) in dst.iter_mut().enumerate().take(n) {
        let hi = if i + ws < n { a[i + ws] } else { 0 };
        let higher = if i + ws + 1 < n { a[i + ws + 1] } else { 0 };
        *d = if bs == 0 {
            hi
        } else {
            (hi >> bs) | (higher << (64 - bs))
        };
    }
    if fill {
        for i in (width as u64 - amount)..width as u64 {
            set_bit(dst, i as u32, true);
        }
    }
    clamp(dst, width);
}

/// Copies `width` bits of `src` starting at bit `lo` into `dst` (bit 0 upward).
pub fn extract(dst: &mut [u64], src: &[u64], lo: u32, width: u32) {
    let n = words_for(width);
    let ws = (lo / 64) as usize;
    let bs = lo % 64;
    for (i, d) in dst.iter_mut().enumerate().take(n) {
        let a = src.get(i + ws).copied().unwrap_or(0);
        let b = src.get(i + ws + 1).copied().unwrap_or(0);
        *d = if bs == 0 {
            a
        } else {
            (a >> bs) | (b << (64 - bs))
        };
    }
    clamp(dst, width);
}

/// ORs the `width`-bit value `src` into `dst` at bit offset `lo`.
/// The destination bits must be zero beforehand.
pub fn deposit(dst: &mut [u64], src: &[u64], lo: u32, width: u32) {
    let ws = (lo / 64) as usize;
    let bs = lo % 64;
    for i in 0..words_for(width) {
        let v = src[i];
        if ws + i < dst.len() {
            dst[ws + i] |= v << bs;
        }
        if bs != 0 && ws + i + 1 < dst.len() {
            dst[ws + i + 1] |= v >> (64 - bs);
        }
    }
}

/// Extends the `from`-bit value `src` to `to` bits, with copies of its sign bit when `signed`.
pub fn extend(dst: &mut [u64], src: &[u64], from: u32, to: u32, signed: bool) {
    let n = words_for(to);
    dst[..n].iter_mut().for_each(|w| *w = 0);
    let m = words_for(from);
    dst[..m].copy_from_slice(&src[..m]);
    if signed && get_bit(src, from - 1) {
        for i in from..to {
            set_bit(dst, i, true);
        }
    }
    clamp(dst, to);
}

/// Low 64 bits of a shift amount, saturated so any set higher word counts as "huge".
pub fn shift_amount(a: &[u64], width: u32) -> u64 {
    let n = words_for(width);
    if a[1..n].iter().any(|&w| w != 0) {
        u64::MAX
    } else {
        a[0]
    }
}

/// True when every bit of the `width`-bit value is one.
pub fn all_ones(a: &[u64], width: u32) -> bool {
    let n = words_for(width);
    a[..n - 1].iter().all(|&w| w == u64::MAX) && a[n - 1] == top_mask(width)
}

/// True when any bit is one.
pub fn any_one(a: &[u64], width: u32) -> bool {
    a[..words_for(width)].iter().any(|&w| w != 0)
}

/// Parity of the value: true when an odd number of bits are one.
pub fn parity(a: &[u64], width: u32) -> bool {
    a[..words_for(width)]
        .iter()
        .fold(0u32, |acc, w| acc + w.count_ones())
        % 2
        == 1
}
