//! The register values against RM0430's formulas, decoded field by field
//! as the manual defines them (not through the crate's own accessors).

use clock_tree::nucleo_f413zh as board;
use clock_tree::{BaudError, Brr, ClockError, ClockPlan, Limits, PllSource};

/// RCC_PLLCFGR fields.
struct PllFields {
    m: u64,
    n: u64,
    p: u64,
    hse: bool,
    q: u64,
    r: u64,
}

fn decode_pllcfgr(v: u32) -> PllFields {
    let v = u64::from(v);
    PllFields {
        m: v & 0x3F,
        n: (v >> 6) & 0x1FF,
        // PLLP: 00 = 2, 01 = 4, 10 = 6, 11 = 8.
        p: [2, 4, 6, 8][((v >> 16) & 0b11) as usize],
        hse: v & (1 << 22) != 0,
        q: (v >> 24) & 0xF,
        r: (v >> 28) & 0x7,
    }
}

/// APB prescaler from a PPRE field (RM0430, RCC_CFGR): 0xx = 1, 100 = 2 .. 111 = 16.
fn ppre_div(field: u32) -> u64 {
    if field & 0b100 == 0 { 1 } else { 2 << (field & 0b11) }
}

/// Checks a plan's registers give `sysclk` from `src_hz` within the F413's
/// limits; returns (APB1, APB2) clocks.
fn check_registers(plan: &ClockPlan, src_hz: u64, sysclk: u64) -> (u64, u64) {
    let f = decode_pllcfgr(plan.pllcfgr());
    assert!((2..=63).contains(&f.m), "PLLM {}", f.m);
    assert!((50..=432).contains(&f.n), "PLLN {}", f.n);
    assert!((2..=15).contains(&f.q), "PLLQ {}", f.q);
    assert!((2..=7).contains(&f.r), "PLLR {}", f.r);
    // f(VCO in) = src / M in 1..2 MHz; f(VCO) = f(VCO in) x N in 100..432 MHz.
    assert!(src_hz >= f.m * 1_000_000 && src_hz <= f.m * 2_000_000, "VCO input of M = {}", f.m);
    let vco_num = src_hz * f.n; // VCO = vco_num / m
    assert!(vco_num >= 100_000_000 * f.m && vco_num <= 432_000_000 * f.m, "VCO output");
    // f(PLL out) = VCO / P, exactly the core clock.
    assert_eq!(vco_num, sysclk * f.m * f.p, "{src_hz} Hz x {} / ({} x {}) != {sysclk}", f.n, f.m, f.p);
    // The 48 MHz domain at most 48 MHz.
    assert!(vco_num <= 48_000_000 * f.m * f.q, "PLL48CLK over 48 MHz");
    let cfgr = plan.cfgr();
    assert_eq!(cfgr & 0b11, 0b10, "SW selects the PLL");
    assert_eq!((cfgr >> 4) & 0xF, 0, "HPRE: AHB undivided");
    let apb1 = sysclk / ppre_div((cfgr >> 10) & 0b111);
    let apb2 = sysclk / ppre_div((cfgr >> 13) & 0b111);
    assert!(apb1 <= 50_000_000 && apb2 <= 100_000_000, "APB1 {apb1}, APB2 {apb2}");
    // Wait states (RM0430, flash wait states at 2.7-3.6 V): 0 up to 25 MHz, 1 up to 50, 2 up to 75, 3 up to 100.
    let table = [(25_000_000, 0), (50_000_000, 1), (75_000_000, 2), (100_000_000, 3)];
    let want = table.iter().find(|&&(top, _)| sysclk <= top).map(|&(_, ws)| ws).expect("within 100 MHz");
    let acr = plan.flash_acr();
    assert_eq!(acr & 0xF, want, "LATENCY at {sysclk} Hz");
    assert_eq!(acr & 0x700, 0x700, "prefetch and both caches on");
    (apb1, apb2)
}

#[test]
fn the_boards_core_runs_at_100_mhz_from_either_oscillator() {
    for (plan, src) in [(board::FROM_HSE, u64::from(board::HSE_HZ)), (board::FROM_HSI, 16_000_000)] {
        let (apb1, apb2) = check_registers(&plan, src, 100_000_000);
        assert_eq!((apb1, apb2), (50_000_000, 100_000_000));
        // Timers on a divided APB1 run at twice its clock: TIM2 counts core cycles.
        assert_eq!(plan.apb1_timer_clock(), 100_000_000);
    }
    // The manual's recommended 2 MHz VCO input from the 8 MHz clock.
    assert_eq!(decode_pllcfgr(board::FROM_HSE.pllcfgr()).m, 4);
    assert!(decode_pllcfgr(board::FROM_HSE.pllcfgr()).hse);
    assert!(!decode_pllcfgr(board::FROM_HSI.pllcfgr()).hse);
}

/// USART_BRR with OVER8 = 0 (RM0430, fractional baud rate generation): USARTDIV = mantissa + fraction / 16,
/// baud = fPCLK / (16 x USARTDIV). Returns the rate as a fraction (num, den).
fn brr_rate(pclk: u64, brr: u16) -> (u64, u64) {
    let mantissa = u64::from(brr >> 4);
    let fraction = u64::from(brr & 0xF);
    // 16 x (mantissa + fraction / 16) = 16 x mantissa + fraction.
    (pclk, 16 * mantissa + fraction)
}

#[test]
fn the_manuals_worked_baud_example() {
    // RM0430, baud-rate error table (fPCLK = 8 MHz, oversampling by 16): 115.2 KBps is
    // programmed as USARTDIV 4.3125 and runs at 115.942 KBps, 0.64% fast.
    let brr = Brr::new(8_000_000, 115_200).expect("115 200 baud from 8 MHz");
    assert_eq!(brr.value, 0x45, "USARTDIV 4.3125 = 4 + 5/16");
    assert_eq!(brr.actual, 115_942);
}

#[test]
fn every_link_runs_at_the_same_rate_within_one_percent() {
    let plan = board::FROM_HSE;
    for (brr, pclk, baud) in [
        (board::NEIGHBOUR_APB1, plan.pclk1(), board::NEIGHBOUR_BAUD),
        (board::NEIGHBOUR_APB2, plan.pclk2(), board::NEIGHBOUR_BAUD),
        (board::HOST_APB1, plan.pclk1(), board::HOST_BAUD),
    ] {
        let (num, den) = brr_rate(u64::from(pclk), brr.value);
        let baud = u64::from(baud);
        // |num/den - baud| <= baud / 100.
        assert!(num.abs_diff(baud * den) * 100 <= baud * den, "{pclk} Hz / BRR {:#x} vs {baud}", brr.value);
    }
    // Both ends of a neighbour link (one on each bus) run at exactly 3.125 Mbaud.
    assert_eq!(brr_rate(50_000_000, board::NEIGHBOUR_APB1.value), (50_000_000, 16));
    assert_eq!(brr_rate(100_000_000, board::NEIGHBOUR_APB2.value), (100_000_000, 32));
}

#[test]
fn three_mbaud_is_refused_at_the_boards_bus_clocks() {
    // 50 MHz / 3 Mbaud = 16.67: the nearest divisor, 17, is 2% slow.
    assert_eq!(Brr::new(50_000_000, 3_000_000), Err(BaudError::Inexact { nearest: 2_941_176 }));
    // 100 MHz / 3 Mbaud = 33.3: 33 is 1.01% fast.
    assert_eq!(Brr::new(100_000_000, 3_000_000), Err(BaudError::Inexact { nearest: 3_030_303 }));
    assert_eq!(Brr::new(16_000_000, 3_125_000), Err(BaudError::TooFast));
    assert_eq!(Brr::new(100_000_000, 1_000), Err(BaudError::TooSlow));
}

#[test]
fn a_plan_exists_exactly_when_some_pll_factors_give_the_clock() {
    // Every core clock in whole MHz from each source: the plan's registers
    // give it exactly, or a brute-force search of the manual's ranges finds
    // no factors that do.
    for src in [PllSource::Hsi, PllSource::Hse(8_000_000), PllSource::Hse(25_000_000)] {
        let s = u64::from(src.hz());
        for mhz in 1..=100u64 {
            let sysclk = mhz * 1_000_000;
            let exists = (2..=63u64).any(|m| {
                s.is_multiple_of(m)
                    && (1_000_000..=2_000_000).contains(&(s / m))
                    && (50..=432u64).any(|n| {
                        let vco = s / m * n;
                        (100_000_000..=432_000_000).contains(&vco)
                            && [2, 4, 6, 8].iter().any(|&p| vco == sysclk * p)
                    })
            });
            match ClockPlan::new(src, sysclk as u32, Limits::STM32F413) {
                Ok(plan) => {
                    assert!(exists, "{sysclk} Hz planned without factors");
                    check_registers(&plan, s, sysclk);
                }
                Err(e) => {
                    assert_eq!(e, ClockError::NoExactFactors);
                    assert!(!exists, "{sysclk} Hz from {s} Hz has factors but no plan");
                }
            }
        }
    }
    assert_eq!(ClockPlan::new(PllSource::Hsi, 101_000_000, Limits::STM32F413), Err(ClockError::AboveLimit));
}
