//! Bit strings: the writer and reader of the compact point batch, zigzag, Exp-Golomb codes
//! and the adaptive order of the second differences.

/// Longest Exp-Golomb code value (bits); longer ones are malformed.
pub(super) const MAX_CODE_BITS: u32 = 62;

pub(super) fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

pub(super) fn unzigzag(u: u64) -> i64 {
    ((u >> 1) as i64) ^ -((u & 1) as i64)
}

#[derive(Debug, Default)]
pub(super) struct BitWriter {
    bytes: Vec<u8>,
    acc: u64,
    n_acc: u32,
}

impl BitWriter {
    /// A writer with room for `bytes` bytes (no reallocation while the estimate holds).
    pub(super) fn with_capacity(bytes: usize) -> BitWriter {
        BitWriter { bytes: Vec::with_capacity(bytes), acc: 0, n_acc: 0 }
    }

    /// Writes the low `count` bits of `value`, most significant first.
    pub(super) fn bits(&mut self, value: u64, count: u32) {
        if count > 32 {
            self.bits(value >> 32, count - 32);
            self.bits(value & 0xffff_ffff, 32);
            return;
        }
        if count == 0 {
            return;
        }
        let value = value & ((1u64 << count) - 1);
        self.acc = (self.acc << count) | value;
        self.n_acc += count;
        while self.n_acc >= 8 {
            self.n_acc -= 8;
            self.bytes.push((self.acc >> self.n_acc) as u8);
        }
        self.acc &= (1u64 << self.n_acc) - 1;
    }

    pub(super) fn exp_golomb(&mut self, u: u64, k: u32) {
        let v = u + (1u64 << k);
        let len = 64 - v.leading_zeros();
        self.bits(0, len - 1 - k);
        self.bits(v, len);
    }

    pub(super) fn finish(mut self) -> Vec<u8> {
        if self.n_acc > 0 {
            let pad = 8 - self.n_acc;
            self.bits(0, pad);
        }
        self.bytes
    }
}

/// Where a batch decoder gets its bytes: a slice, or bincode's sequence of `u8`.
pub(super) trait ByteSource {
    type Error;
    /// The next byte; an error at the end.
    fn next_byte(&mut self) -> Result<u8, Self::Error>;
    fn malformed(message: &str) -> Self::Error;
}

pub(super) struct BitReader<'a, R: ByteSource> {
    source: &'a mut R,
    byte: u8,
    n_left: u32,
}

impl<'a, R: ByteSource> BitReader<'a, R> {
    pub(super) fn new(source: &'a mut R) -> BitReader<'a, R> {
        BitReader { source, byte: 0, n_left: 0 }
    }

    pub(super) fn bit(&mut self) -> Result<bool, R::Error> {
        if self.n_left == 0 {
            self.byte = self.source.next_byte()?;
            self.n_left = 8;
        }
        self.n_left -= 1;
        Ok((self.byte >> self.n_left) & 1 == 1)
    }

    /// Reads `count` (at most 64) bits, most significant first: what is left of the current
    /// byte, then whole bytes, then the head of the last one.
    pub(super) fn bits(&mut self, count: u32) -> Result<u64, R::Error> {
        let mut v = 0u64;
        let mut left = count;
        while left > 0 {
            if self.n_left == 0 {
                self.byte = self.source.next_byte()?;
                self.n_left = 8;
            }
            let take = left.min(self.n_left);
            let shift = self.n_left - take;
            let chunk = (u32::from(self.byte) >> shift) & ((1u32 << take) - 1);
            // `take` is at most 8: shifting a u64 by it never overflows.
            v = (v << take) | u64::from(chunk);
            self.n_left = shift;
            left -= take;
        }
        Ok(v)
    }

    pub(super) fn exp_golomb(&mut self, k: u32) -> Result<u64, R::Error> {
        let mut zeros = 0;
        while !self.bit()? {
            zeros += 1;
            if zeros + k + 1 > MAX_CODE_BITS {
                return Err(R::malformed("number code too long"));
            }
        }
        if zeros + k + 1 > MAX_CODE_BITS {
            return Err(R::malformed("number code too long"));
        }
        let rest = self.bits(zeros + k)?;
        let v = (1u64 << (zeros + k)) | rest;
        Ok(v - (1u64 << k))
    }

    /// The padding after the last code must be zero bits.
    pub(super) fn finish(&mut self) -> Result<(), R::Error> {
        let mask = (1u32 << self.n_left) - 1;
        if u32::from(self.byte) & mask != 0 {
            return Err(R::malformed("non-zero padding bits"));
        }
        Ok(())
    }
}

/// LOCO-I style running estimate of the Exp-Golomb order of second differences.
#[derive(Debug, Clone, Copy)]
pub(super) struct Adaptive {
    sum: u64,
    count: u64,
}

impl Adaptive {
    pub(super) fn new(k0: u32) -> Adaptive {
        Adaptive { sum: 2 << k0, count: 2 }
    }

    /// The least `k` with `count << k >= sum`, at most 40. `count << k` has as many bits as
    /// `sum` for `k` = the difference of their lengths, so the least is that or one more
    /// (computed, not searched: it is asked for every second difference coded or decoded).
    pub(super) fn order(&self) -> u32 {
        let k = self.count.leading_zeros().saturating_sub(self.sum.leading_zeros());
        let k = if (self.count << k) < self.sum { k + 1 } else { k };
        k.min(40)
    }

    pub(super) fn update(&mut self, u: u64) {
        self.sum = self.sum.saturating_add(u);
        self.count += 1;
        if self.count >= 64 {
            self.sum /= 2;
            self.count /= 2;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The computed order is the searched one of the first version, for every state an
    /// encoder can reach and beyond (a reader of a malformed batch can reach any sum).
    #[test]
    fn the_order_is_the_least_k_that_covers_the_sum() {
        let searched = |a: &Adaptive| {
            let mut k = 0;
            while (a.count << k) < a.sum && k < 40 {
                k += 1;
            }
            k
        };
        let sums = (0..64).flat_map(|b| [1u64 << b, (1u64 << b) - 1, (1u64 << b) + 1]);
        for sum in sums.chain([0, 3, 5, 1000, u64::MAX]) {
            for count in 1..=64 {
                let a = Adaptive { sum, count };
                assert_eq!(a.order(), searched(&a), "sum {sum}, count {count}");
            }
        }
    }

    /// Bits read several at a time are the bits written, at every alignment and width.
    #[test]
    fn bits_read_back_at_every_alignment() {
        struct Bytes(std::vec::IntoIter<u8>);
        impl ByteSource for Bytes {
            type Error = ();
            fn next_byte(&mut self) -> Result<u8, ()> {
                self.0.next().ok_or(())
            }
            fn malformed(_: &str) -> Self::Error {}
        }
        for lead in 0..8 {
            for width in 0..=64 {
                let value = 0xdead_beef_cafe_f00d_u64 & width_mask(width);
                let mut w = BitWriter::default();
                w.bits(0b1011_0110, lead);
                w.bits(value, width);
                w.bits(0b101, 3);
                let mut source = Bytes(w.finish().into_iter());
                let mut r = BitReader::new(&mut source);
                assert_eq!(r.bits(lead), Ok(0b1011_0110 & width_mask(lead)), "lead {lead}");
                assert_eq!(r.bits(width), Ok(value), "lead {lead}, width {width}");
                assert_eq!(r.bits(3), Ok(0b101), "lead {lead}, width {width}");
            }
        }
    }

    fn width_mask(width: u32) -> u64 {
        if width == 64 { u64::MAX } else { (1u64 << width) - 1 }
    }
}
