//! Puts the board's memory map where cortex-m-rt's link.x finds it.
use std::{env, fs, path::PathBuf};

fn main() {
    let board = if env::var_os("CARGO_FEATURE_MPS2_AN385").is_some() {
        "mps2-an385"
    } else if env::var_os("CARGO_FEATURE_STM32F413").is_some() {
        "stm32f413"
    } else if env::var_os("CARGO_FEATURE_NETDUINOPLUS2").is_some() {
        "netduinoplus2"
    } else {
        panic!("choose a board: --features mps2-an385, stm32f413 or netduinoplus2");
    };
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let map = format!("memory/{board}.x");
    fs::copy(&map, out.join("memory.x")).expect("memory map of the board");
    println!("cargo:rustc-link-search={}", out.display());
    // The real board moves its neighbour links' bytes by DMA (unless built
    // with `interrupt-links`); the emulated STM32 has no DMA model, and
    // moves them by interrupt.
    println!("cargo::rustc-check-cfg=cfg(dma_links)");
    if board == "stm32f413" {
        if env::var_os("CARGO_FEATURE_INTERRUPT_LINKS").is_none() {
            println!("cargo:rustc-cfg=dma_links");
        }
        // defmt's log strings live in the ELF, not the flash: its linker script places them.
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
    println!("cargo:rerun-if-changed={map}");
    println!("cargo:rerun-if-changed=build.rs");
}
