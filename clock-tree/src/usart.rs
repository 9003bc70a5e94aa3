//! The U(S)ART baud-rate register.

/// A baud-rate register value and the rate it gives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Brr {
    /// USART_BRR with oversampling by 16 (OVER8 = 0): DIV_Mantissa `[15:4]`,
    /// DIV_Fraction `[3:0]`, that is USARTDIV in sixteenths.
    pub value: u16,
    /// The rate the peripheral then runs at, baud (rounded down).
    pub actual: u32,
}

/// Why a rate cannot be set.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BaudError {
    /// Above the peripheral clock / 16 (USARTDIV below 1).
    TooFast,
    /// Below what a 16-bit register divides to.
    TooSlow,
    /// The nearest divisor is more than 1% off the rate asked for.
    Inexact {
        /// The nearest rate the clock divides to, baud.
        nearest: u32,
    },
}

/// Error allowed between the rate asked for and the rate set, in parts per
/// 10 000: 1%, well inside the 3.75% the receivers tolerate together
/// (RM0430, USART receiver tolerance to clock deviation) when both ends are set the same way.
pub const TOLERANCE_PER_10K: u64 = 100;

impl Brr {
    /// The register value for `baud` on a peripheral clocked at `pclk` Hz.
    ///
    /// With oversampling by 16, baud = pclk / (16 x USARTDIV) and the
    /// register holds USARTDIV in sixteenths, so it is pclk / baud rounded to
    /// the nearest integer.
    pub const fn new(pclk: u32, baud: u32) -> Result<Brr, BaudError> {
        if baud == 0 {
            return Err(BaudError::TooSlow);
        }
        let value = (pclk as u64 + baud as u64 / 2) / baud as u64;
        if value < 16 {
            return Err(BaudError::TooFast);
        }
        if value > u16::MAX as u64 {
            return Err(BaudError::TooSlow);
        }
        let actual = (pclk as u64 / value) as u32;
        let off = (pclk as u64).abs_diff(value * baud as u64);
        if off * 10_000 > TOLERANCE_PER_10K * value * baud as u64 {
            return Err(BaudError::Inexact { nearest: actual });
        }
        Ok(Brr { value: value as u16, actual })
    }
}
