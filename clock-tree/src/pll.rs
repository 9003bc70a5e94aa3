//! The main PLL, the bus prescalers and the flash wait states.

/// A chip's clock limits (datasheet, "general operating conditions").
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Highest core (AHB) clock, Hz.
    pub sysclk_max: u32,
    /// Highest APB1 clock, Hz.
    pub pclk1_max: u32,
    /// Highest APB2 clock, Hz.
    pub pclk2_max: u32,
    /// Flash access time: the core clock one wait state covers, Hz
    /// (the wait-state table's step at the board's supply voltage).
    pub flash_step: u32,
}

impl Limits {
    /// STM32F413 at 2.7-3.6 V (datasheet DS11581; RM0430: 25 MHz per flash wait state).
    pub const STM32F413: Limits = Limits {
        sysclk_max: 100_000_000,
        pclk1_max: 50_000_000,
        pclk2_max: 100_000_000,
        flash_step: 25_000_000,
    };
}

/// What feeds the PLL.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PllSource {
    /// The 16 MHz internal RC oscillator.
    Hsi,
    /// The external clock, at this frequency (Hz).
    Hse(u32),
}

impl PllSource {
    /// HSI frequency (RM0430, clocks).
    pub const HSI_HZ: u32 = 16_000_000;

    /// The source's frequency, Hz.
    pub const fn hz(self) -> u32 {
        match self {
            PllSource::Hsi => Self::HSI_HZ,
            PllSource::Hse(hz) => hz,
        }
    }
}

/// Why no clock plan exists.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClockError {
    /// The core clock asked for is above the chip's limit.
    AboveLimit,
    /// No PLL factors within the manual's ranges give the clock exactly.
    NoExactFactors,
}

/// PLL ranges (RM0430, RCC_PLLCFGR): VCO input 1-2 MHz, VCO output 100-432 MHz.
const VCO_IN_MIN: u32 = 1_000_000;
const VCO_IN_MAX: u32 = 2_000_000;
const VCO_OUT_MIN: u64 = 100_000_000;
const VCO_OUT_MAX: u64 = 432_000_000;
const PLLN_MIN: u32 = 50;
const PLLN_MAX: u32 = 432;
const PLLM_MIN: u32 = 2;
const PLLM_MAX: u32 = 63;
/// The 48 MHz domain (USB, SDIO) may not run faster than this.
const Q_DOMAIN_MAX: u64 = 48_000_000;

/// A core clock from the main PLL and the bus clocks under it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockPlan {
    /// What feeds the PLL.
    pub source: PllSource,
    /// Input divider (PLLM).
    pub m: u32,
    /// VCO multiplier (PLLN).
    pub n: u32,
    /// Core-clock divider (PLLP: 2, 4, 6 or 8).
    pub p: u32,
    /// 48 MHz-domain divider (PLLQ).
    pub q: u32,
    /// APB1 prescaler (1, 2, 4, 8 or 16).
    pub apb1_div: u32,
    /// APB2 prescaler.
    pub apb2_div: u32,
    /// Flash wait states.
    pub wait_states: u32,
}

impl ClockPlan {
    /// The plan for a core clock of `sysclk` Hz from `source` within `limits`:
    /// the PLL factors with the highest VCO input frequency (the manual
    /// recommends 2 MHz, for the least jitter) and then the smallest PLLP;
    /// the smallest bus prescalers that keep each APB within its limit; the
    /// fewest wait states that cover the core clock.
    pub const fn new(source: PllSource, sysclk: u32, limits: Limits) -> Result<ClockPlan, ClockError> {
        if sysclk > limits.sysclk_max || sysclk == 0 {
            return Err(ClockError::AboveLimit);
        }
        let src = source.hz();
        let mut m = PLLM_MIN;
        let mut found: Option<(u32, u32, u32)> = None;
        while m <= PLLM_MAX && found.is_none() {
            let vco_in = src / m;
            if src.is_multiple_of(m) && vco_in >= VCO_IN_MIN && vco_in <= VCO_IN_MAX {
                let mut p = 2;
                while p <= 8 && found.is_none() {
                    let vco = sysclk as u64 * p as u64;
                    if vco.is_multiple_of(vco_in as u64) && vco >= VCO_OUT_MIN && vco <= VCO_OUT_MAX {
                        let n = (vco / vco_in as u64) as u32;
                        if n >= PLLN_MIN && n <= PLLN_MAX {
                            found = Some((m, n, p));
                        }
                    }
                    p += 2;
                }
            }
            m += 1;
        }
        let Some((m, n, p)) = found else {
            return Err(ClockError::NoExactFactors);
        };
        let vco = src as u64 / m as u64 * n as u64;
        let mut q = vco.div_ceil(Q_DOMAIN_MAX) as u32;
        if q < 2 {
            q = 2;
        }
        Ok(ClockPlan {
            source,
            m,
            n,
            p,
            q,
            apb1_div: apb_div(sysclk, limits.pclk1_max),
            apb2_div: apb_div(sysclk, limits.pclk2_max),
            wait_states: (sysclk - 1) / limits.flash_step,
        })
    }

    /// The core (AHB) clock, Hz.
    pub const fn sysclk(&self) -> u32 {
        (self.source.hz() as u64 / self.m as u64 * self.n as u64 / self.p as u64) as u32
    }

    /// The APB1 clock, Hz.
    pub const fn pclk1(&self) -> u32 {
        self.sysclk() / self.apb1_div
    }

    /// The APB2 clock, Hz.
    pub const fn pclk2(&self) -> u32 {
        self.sysclk() / self.apb2_div
    }

    /// The clock of the timers on APB1 (TIM2-TIM5): twice the bus clock
    /// when the bus is divided (RM0430, clock tree).
    pub const fn apb1_timer_clock(&self) -> u32 {
        if self.apb1_div == 1 { self.pclk1() } else { 2 * self.pclk1() }
    }

    /// RCC_PLLCFGR: PLLM `[5:0]`, PLLN `[14:6]`, PLLP `[17:16]` (0 = /2 .. 3 = /8),
    /// PLLSRC `[22]` (1 = HSE), PLLQ `[27:24]`, PLLR `[30:28]` (kept at 2: unused).
    pub const fn pllcfgr(&self) -> u32 {
        let src = match self.source {
            PllSource::Hsi => 0,
            PllSource::Hse(_) => 1 << 22,
        };
        self.m | (self.n << 6) | ((self.p / 2 - 1) << 16) | src | (self.q << 24) | (2 << 28)
    }

    /// RCC_CFGR with the PLL as the system clock: SW `[1:0]` = 2, HPRE `[7:4]`
    /// = /1, PPRE1 `[12:10]`, PPRE2 `[15:13]`.
    pub const fn cfgr(&self) -> u32 {
        0b10 | (ppre(self.apb1_div) << 10) | (ppre(self.apb2_div) << 13)
    }

    /// FLASH_ACR: LATENCY `[3:0]`, prefetch `[8]`, instruction `[9]` and data `[10]` caches.
    pub const fn flash_acr(&self) -> u32 {
        self.wait_states | (1 << 8) | (1 << 9) | (1 << 10)
    }
}

/// The smallest APB prescaler (a power of two up to 16) keeping `hclk / div <= max`.
const fn apb_div(hclk: u32, max: u32) -> u32 {
    let mut div = 1;
    while hclk / div > max && div < 16 {
        div *= 2;
    }
    div
}

/// PPREx field for a prescaler: 0 = /1, 0b100 = /2 .. 0b111 = /16.
const fn ppre(div: u32) -> u32 {
    match div {
        1 => 0,
        2 => 0b100,
        4 => 0b101,
        8 => 0b110,
        _ => 0b111,
    }
}
