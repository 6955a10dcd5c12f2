//! Bus scan: count the slaves, put them in Init with a clean configuration, give each a station
//! address by position, and read what each one is from its SII.

use std::collections::VecDeque;
use std::time::Duration;

use crate::error::{Error, Result, SiiError};
use crate::ethercat::frame::Command;
use crate::ethercat::master::{mailbox_client::Mailbox, state::AlStatus, Master, Slave, FIRST_STATION_ADDRESS};
use crate::ethercat::registers::{self, FMMU0, SM0};
use crate::ethercat::sii::Sii;

/// How long the slaves may take to fall back to Init at the start of a scan.
const INIT_TIMEOUT: Duration = Duration::from_secs(5);
/// FMMUs the scan clears: a master of the AKD uses FMMU 0 (outputs), 1 (inputs), 2 (mailbox).
pub(crate) const FMMUS_CLEARED: usize = 3;
/// Sync managers the scan clears: the AKD's two mailbox and two process-data ones.
pub(crate) const SMS_CLEARED: usize = 4;

impl Master {
    /// Finds the slaves on the bus, in order, and returns how many there are. Each slave's AL
    /// status is recorded as found ([`Slave::found`]); then every slave is taken to Init with its
    /// FMMUs, sync managers and SYNC outputs cleared, as a fresh start.
    pub fn scan(&mut self) -> Result<usize> {
        self.slaves.clear();
        self.process = None;
        self.clock = None;
        let count = self.datagram_retry(Command::Brd, 0, registers::TYPE, &mut [0u8; 2])?;
        if count == 0 {
            return Ok(0);
        }
        let mut found = Vec::with_capacity(count as usize);
        for position in 0..count {
            let mut registers = [0u8; 6];
            let wkc =
                self.datagram_retry(Command::Aprd, 0u16.wrapping_sub(position), registers::AL_STATUS, &mut registers)?;
            self.expect_wkc(|| format!("APRD of the AL status of position {position}"), 1, wkc)?;
            found.push(AlStatus::from_registers(&registers));
        }
        for position in 0..count {
            let address = FIRST_STATION_ADDRESS + position;
            let wkc = self.datagram_retry(
                Command::Apwr,
                0u16.wrapping_sub(position),
                registers::STATION_ADDRESS,
                &mut address.to_le_bytes(),
            )?;
            self.expect_wkc(|| format!("APWR of the station address to position {position}"), 1, wkc)?;
        }
        for position in 0..count {
            self.reset_to_init(position, FIRST_STATION_ADDRESS + position, INIT_TIMEOUT)?;
        }
        // A clean start: no process data, no mailbox, no SYNC pulses until configured again.
        self.broadcast_write(FMMU0, &[0; FMMUS_CLEARED * registers::FMMU_LEN as usize])?;
        self.broadcast_write(SM0, &[0; SMS_CLEARED * registers::SM_LEN as usize])?;
        self.broadcast_write(registers::DC_ACTIVATION, &[0])?;
        // Taken whole or not at all: a slave that cannot be read leaves no half line behind.
        let slaves = (0..count)
            .zip(found)
            .map(|(position, found)| self.read_slave(position, FIRST_STATION_ADDRESS + position, found))
            .collect::<Result<Vec<_>>>()?;
        self.slaves = slaves;
        Ok(count as usize)
    }

    /// Reads what the slave at `station` is: features, alias and SII.
    fn read_slave(&mut self, position: u16, station: u16, found: AlStatus) -> Result<Slave> {
        let esc_features = self.read_u16(station, registers::FEATURES)?;
        let dc = esc_features & registers::FEATURE_DC != 0
            && self.datagram_retry(Command::Fprd, station, registers::DC_SYSTEM_TIME, &mut [0u8; 8])? == 1;
        let alias = self.read_u16(station, registers::STATION_ALIAS)?;
        // An SII fault names the slave it was found on.
        let of_slave = |error| -> Error { SiiError::OfSlave { position, station, error: Box::new(error) }.into() };
        let image = self.read_sii(station).map_err(|e| match e {
            Error::Sii(error) => of_slave(error),
            other => other,
        })?;
        let sii = Sii::parse(&image).map_err(of_slave)?;
        let mailbox = Mailbox::from_sii(&sii).map_err(of_slave)?;
        Ok(Slave {
            position,
            station_address: station,
            alias,
            dc,
            found,
            sii,
            mailbox,
            emergencies: VecDeque::new(),
            eoe: Default::default(),
            process_data: None,
        })
    }
}
