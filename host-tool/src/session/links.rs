//! The links a run on the in-memory board models: a named preset, with the
//! core clock, the line rates and the byte transfer open to override.

use serde_json::{Value, json};
use sim_board::{LinkPreset, LinkSpec, Transfer};

use crate::error::{HostError, input};

/// A preset and the settings that override it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct LinkChoice {
    /// The board the links start from.
    pub preset: LinkPreset,
    /// Core clock, Hz.
    pub clock_hz: Option<u64>,
    /// Neighbour links' line rate, baud.
    pub baud: Option<u64>,
    /// Host links' line rate, baud.
    pub host_baud: Option<u64>,
    /// How bytes reach memory on the neighbour links (the host link's is
    /// the preset's: on the STM32 boards it has no DMA streams left).
    pub transfer: Option<Transfer>,
}

impl LinkChoice {
    /// The neighbour and host links, checked: a clock of 1 MHz to 1 GHz, and
    /// line rates from 300 baud to one bit per cycle.
    pub fn specs(&self) -> Result<(LinkSpec, LinkSpec), HostError> {
        let clock_hz = self.clock_hz.unwrap_or(self.preset.neighbour().clock_hz);
        if !(1_000_000..=1_000_000_000).contains(&clock_hz) {
            return Err(input(format!("--clock-mhz must be from 1 to 1000, got {}", clock_hz as f64 / 1e6)));
        }
        let rate = |flag: &str, baud: u64| {
            if (300..=clock_hz).contains(&baud) {
                Ok(baud)
            } else {
                Err(input(format!("{flag} must be from 300 to the core clock ({clock_hz} Hz), got {baud}")))
            }
        };
        let pick = |spec: LinkSpec, baud: Option<u64>, flag: &str, transfer: Option<Transfer>| {
            Ok::<_, HostError>(LinkSpec {
                clock_hz,
                baud: rate(flag, baud.unwrap_or(spec.baud))?,
                transfer: transfer.unwrap_or(spec.transfer),
                ..spec
            })
        };
        Ok((
            pick(self.preset.neighbour(), self.baud, "--baud", self.transfer)?,
            pick(self.preset.host(), self.host_baud, "--host-baud", None)?,
        ))
    }
}

impl LinkChoice {
    /// Sets `opts`' links, and the loop pass the preset's board pays, to
    /// this choice.
    pub fn apply(&self, opts: &mut crate::plan::options::RenderOptions) -> Result<(), HostError> {
        let (link, host) = self.specs()?;
        opts.sim.link = link;
        opts.sim.host_link = host;
        opts.sim.cost.pass = self.preset.loop_pass();
        opts.link_preset = self.preset;
        Ok(())
    }
}

/// A link as the summary describes it.
pub fn spec_json(spec: &LinkSpec) -> Value {
    let model = spec.model();
    json!({
        "clock_hz": spec.clock_hz,
        "baud": spec.baud,
        "transfer": spec.transfer.name(),
        "wire_cycles_per_byte": model.byte,
        "cpu_cycles_per_byte": model.byte_cpu,
        "cpu_cycles_per_frame": model.frame_cpu,
        "latency_cycles": model.latency,
    })
}

/// The preset of a name, for the command line.
pub fn preset_named(name: &str) -> Result<LinkPreset, String> {
    LinkPreset::ALL.into_iter().find(|p| p.name() == name).ok_or_else(|| {
        let names: Vec<&str> = LinkPreset::ALL.iter().map(|p| p.name()).collect();
        format!("unknown link preset '{name}' (one of {})", names.join(", "))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_replace_the_presets_values() {
        let choice = LinkChoice {
            preset: LinkPreset::F413,
            clock_hz: Some(50_000_000),
            baud: Some(1_000_000),
            host_baud: None,
            transfer: Some(Transfer::Polled),
        };
        let (n, h) = choice.specs().unwrap();
        // 50 MHz x 10 bits / 1 Mbaud = 500 cycles a byte, polled; the host
        // keeps its rate and its DMA.
        assert_eq!((n.model().byte, n.model().byte_cpu, n.transfer), (500, 16, Transfer::Polled));
        assert_eq!((h.baud, h.clock_hz, h.transfer), (921_600, 50_000_000, Transfer::Dma));
    }

    #[test]
    fn out_of_range_settings_are_refused() {
        let bad = |c: LinkChoice| c.specs().unwrap_err().exit_code();
        assert_eq!(bad(LinkChoice { clock_hz: Some(0), ..LinkChoice::default() }), 17);
        assert_eq!(bad(LinkChoice { baud: Some(299), ..LinkChoice::default() }), 17);
        assert_eq!(bad(LinkChoice { host_baud: Some(200_000_000), ..LinkChoice::default() }), 17);
        assert!(preset_named("f413").is_ok() && preset_named("fast").is_err());
    }
}
