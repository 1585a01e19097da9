//! The mapping between the controllers' own types (`control`) and the wire contract
//! (`ipc-types`): channel counts and status bits.

use control::{Dimensions, status};
use ipc_types::{ChannelCounts, actuation_status};

/// The controller dimensions of the contract's channel counts.
pub fn dimensions(c: ChannelCounts) -> Dimensions {
    Dimensions::new(
        c.n_y as usize,
        c.n_z as usize,
        c.n_r as usize,
        c.n_u as usize,
    )
}

/// The contract's channel counts of a controller's dimensions, refused when a count
/// exceeds the contract's capacity.
pub fn channel_counts(d: Dimensions) -> Result<ChannelCounts, String> {
    ChannelCounts::new(d.n_y, d.n_z, d.n_r, d.n_u)
}

/// The actuation status bits of a controller step's [`status`] bits.
pub fn actuation_status(step: u32) -> u32 {
    let mut out = actuation_status::OK;
    if step & status::SATURATED != 0 {
        out |= actuation_status::SATURATED;
    }
    if step & status::CONTROLLER_FAULT != 0 {
        out |= actuation_status::CONTROLLER_FAULT;
    }
    if step & status::FALLBACK != 0 {
        out |= actuation_status::FALLBACK;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_step_status_bit_maps_to_its_actuation_bit() {
        assert_eq!(actuation_status(status::OK), actuation_status::OK);
        assert_eq!(
            actuation_status(status::SATURATED),
            actuation_status::SATURATED
        );
        assert_eq!(
            actuation_status(status::CONTROLLER_FAULT),
            actuation_status::CONTROLLER_FAULT
        );
        assert_eq!(
            actuation_status(status::FALLBACK),
            actuation_status::FALLBACK
        );
        assert_eq!(
            actuation_status(status::SATURATED | status::FALLBACK),
            actuation_status::SATURATED | actuation_status::FALLBACK
        );
    }

    #[test]
    fn counts_round_trip_through_dimensions() {
        let c = ChannelCounts::new(2, 1, 0, 3).unwrap();
        assert_eq!(channel_counts(dimensions(c)).unwrap(), c);
    }
}
