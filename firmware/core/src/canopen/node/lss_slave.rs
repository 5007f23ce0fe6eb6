//! The node's side of LSS ([`crate::canopen::lss`]): the node id at boot (stored, else the
//! one the node was built with), the requests, and storing the configuration.

use super::{frame, ControlStep, Node, ParamStorage, StorageError};
use crate::canopen::frame::CanFrame;
use crate::canopen::lss::{Action, Lss, LssConfig, LSS_SLAVE, UNCONFIGURED};

impl<S: ParamStorage, C: ControlStep> Node<S, C> {
    /// Power-on and reset node: the stored LSS configuration if there is a usable one.
    pub(super) fn lss_boot(&mut self) {
        let stored = self.storage.load_lss().filter(|c| (1..=127).contains(&c.node_id) || c.node_id == UNCONFIGURED);
        let c = stored.unwrap_or(LssConfig { node_id: self.boot_id, bit_timing: 0 });
        self.cfg.node_id = c.node_id;
        self.lss = Lss::new(c);
    }

    /// One frame on 0x7E5.
    pub(super) fn lss_frame(&mut self, now_us: u64, d: &[u8], tx: &mut impl FnMut(CanFrame)) {
        if d.len() != 8 {
            self.dropped = self.dropped.saturating_add(1);
            return;
        }
        let ident = self.cfg.identity;
        match self.lss.on_request(d, &ident, self.cfg.node_id) {
            Action::None => {}
            Action::Respond(p) => tx(frame(LSS_SLAVE, p, 8)),
            Action::Store => {
                // CiA 305: 0 stored, 1 not supported, 2 storage media access error
                let e = match self.storage.save_lss(self.lss.pending) {
                    Ok(()) => 0,
                    Err(StorageError::Unsupported) => 1,
                    Err(_) => 2,
                };
                tx(frame(LSS_SLAVE, [0x17, e, 0, 0, 0, 0, 0, 0], 8));
            }
            Action::ResetCommunication => self.reset_communication(now_us),
        }
    }

    /// The LSS slave's state (mode, pending configuration, the last activate bit timing).
    pub fn lss(&self) -> &Lss {
        &self.lss
    }
}
