//! A valid/ready port group and the transaction it carries.

use crate::design::{Design, PortId};
use crate::error::Result;
use golden::bits::Bits;

/// One transaction: the payload ports' values, in the group's payload order.
pub type Transaction = Vec<Bits>;

/// The ports of one valid/ready stream.
#[derive(Clone, Debug)]
pub struct StreamPorts {
    /// The valid signal (1 bit).
    pub valid: PortId,
    /// The ready signal (1 bit).
    pub ready: PortId,
    /// Payload ports, in transaction order.
    pub payload: Vec<PortId>,
    /// Payload port names (for reports).
    pub payload_names: Vec<String>,
}

impl StreamPorts {
    /// Look the named ports up in `design`.
    pub fn new(design: &Design, valid: &str, ready: &str, payload: &[&str]) -> Result<StreamPorts> {
        Ok(StreamPorts {
            valid: design.port_id(valid)?,
            ready: design.port_id(ready)?,
            payload: payload
                .iter()
                .map(|p| design.port_id(p))
                .collect::<Result<_>>()?,
            payload_names: payload.iter().map(|p| p.to_string()).collect(),
        })
    }
}
