//! CoE SDO information client: the object list and the descriptions of objects and entries,
//! each reply gathered from as many fragments as the slave needs.

use crate::error::{Error, MailboxError, Result};
use crate::ethercat::coe::{
    self, CoeService, EntryDescription, ObjectCode, ObjectDescription, OdListType, SdoInfoHeader, SdoInfoOpcode,
    SDO_INFO_HEADER_LEN,
};
use crate::ethercat::master::sdo::body_of_service;
use crate::ethercat::master::Master;

/// An object's description, owned.
#[derive(Clone, Debug, PartialEq, Eq)]
// Python gets a dict keyed by the field names (akd_ros._native): renaming a field renames a key.
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct ObjectInfo {
    /// Object index.
    pub index: u16,
    /// Data type code, see [`coe::data_type`].
    pub data_type: u16,
    /// Highest subindex.
    pub max_subindex: u8,
    /// Object code.
    pub object_code: ObjectCode,
    /// Name.
    pub name: String,
}

/// Whether a drive's answer to the object description of a manufacturer object confirms that
/// it is the AKD parameter named `parameter` (e.g. "FBUS.PARAM02"), so that it may be written
/// or its value trusted: only a description whose name names it
/// ([`coe::names_parameter`]). An SDO abort (no such object, or no SDO information) leaves it
/// unconfirmed; any other error (the mailbox failing) is the caller's error.
pub fn parameter_confirmed(description: Result<ObjectInfo>, parameter: &str) -> Result<bool> {
    match description {
        Ok(object) => Ok(coe::names_parameter(&object.name, parameter)),
        Err(crate::error::Error::SdoAbort { .. }) => Ok(false),
        Err(e) => Err(e),
    }
}

/// An entry's description, owned.
#[derive(Clone, Debug, PartialEq, Eq)]
// Python gets a dict keyed by the field names (akd_ros._native): renaming a field renames a key.
#[cfg_attr(feature = "python", derive(pyo3::IntoPyObject))]
pub struct EntryInfo {
    /// Subindex.
    pub subindex: u8,
    /// Data type code.
    pub data_type: u16,
    /// Length in bits.
    pub bit_length: u16,
    /// Access bits, see [`coe::access`].
    pub access: u16,
    /// Name.
    pub name: String,
}

impl Master {
    /// One SDO information request; returns the data of every response fragment joined.
    /// `index`/`subindex` name the object in an error.
    fn sdo_info(
        &mut self,
        position: u16,
        opcode: SdoInfoOpcode,
        request: &[u8],
        index: u16,
        subindex: u8,
    ) -> Result<Vec<u8>> {
        let header = SdoInfoHeader { opcode, incomplete: false, fragments_left: 0 };
        let mut reply = self.coe_transaction(position, |out| coe::write_info_message(out, 0, header, request))?;
        let mut data = Vec::new();
        loop {
            let body = body_of_service(position, &reply, CoeService::SdoInformation, "an SDO information request")?;
            let info = SdoInfoHeader::decode(body)?;
            let payload = &body[SDO_INFO_HEADER_LEN..];
            if info.opcode == SdoInfoOpcode::SdoInfoErrorRequest {
                let code = payload
                    .get(..4)
                    .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .ok_or(MailboxError::InfoErrorWithoutCode)?;
                return Err(Error::sdo_abort(index, subindex, coe::SdoAbortCode(code)));
            }
            if Some(info.opcode) != opcode.response() {
                return Err(MailboxError::UnexpectedOpcode {
                    slave: position,
                    asked: opcode.name(),
                    got: info.opcode.name(),
                    expected: opcode.response().map_or("none", |o| o.name()),
                }
                .into());
            }
            data.extend_from_slice(payload);
            if !info.incomplete {
                return Ok(data);
            }
            reply = self.mailbox_receive(position, self.mailbox_timeout)?;
        }
    }

    /// The indices of the objects in one of the slave's object lists.
    pub(super) fn sdo_object_list(&mut self, position: u16, list_type: OdListType) -> Result<Vec<u16>> {
        let data =
            self.sdo_info(position, SdoInfoOpcode::GetOdListRequest, &u16::from(list_type).to_le_bytes(), 0, 0)?;
        // The first fragment starts with the list type; the indices follow, two bytes each.
        let indices = data.get(2..).ok_or(MailboxError::OdListWithoutType)?;
        Ok(indices.chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]])).collect())
    }

    /// The description of object `index`.
    pub(super) fn sdo_object_description(&mut self, position: u16, index: u16) -> Result<ObjectInfo> {
        let data =
            self.sdo_info(position, SdoInfoOpcode::GetObjectDescriptionRequest, &index.to_le_bytes(), index, 0)?;
        let d = ObjectDescription::decode(&data)?;
        if d.index != index {
            return Err(MailboxError::WrongDescription {
                asked: format!("0x{index:04X}"),
                got: format!("0x{:04X}", d.index),
            }
            .into());
        }
        Ok(ObjectInfo {
            index: d.index,
            data_type: d.data_type,
            max_subindex: d.max_subindex,
            object_code: d.object_code,
            name: d.name.to_owned(),
        })
    }

    /// The description of entry `index:subindex` (without the optional values).
    pub(super) fn sdo_entry_description(&mut self, position: u16, index: u16, subindex: u8) -> Result<EntryInfo> {
        let [lo, hi] = index.to_le_bytes();
        let request = [lo, hi, subindex, 0];
        let data = self.sdo_info(position, SdoInfoOpcode::GetEntryDescriptionRequest, &request, index, subindex)?;
        let d = EntryDescription::decode(&data)?;
        if (d.index, d.subindex) != (index, subindex) {
            return Err(MailboxError::WrongDescription {
                asked: format!("0x{index:04X}:{subindex:02X}"),
                got: format!("0x{:04X}:{:02X}", d.index, d.subindex),
            }
            .into());
        }
        Ok(EntryInfo {
            subindex: d.subindex,
            data_type: d.data_type,
            bit_length: d.bit_length,
            access: d.access,
            name: d.name.to_owned(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::{Error, MailboxError};
    use crate::ethercat::coe::{ObjectCode, SdoAbortCode};

    #[test]
    fn a_parameter_is_confirmed_only_where_the_slave_names_the_object_so() {
        let described = |name: &str| {
            Ok(ObjectInfo {
                index: 0x2001,
                data_type: 7,
                max_subindex: 0,
                object_code: ObjectCode::Var,
                name: name.into(),
            })
        };
        assert!(parameter_confirmed(described("VENDOR.PARAM01"), "VENDOR.PARAM01").unwrap());
        assert!(!parameter_confirmed(described("Position offset"), "VENDOR.PARAM01").unwrap());
        let no_object = Error::sdo_abort(0x2001, 0, SdoAbortCode::NO_SUCH_OBJECT);
        assert!(!parameter_confirmed(Err(no_object), "VENDOR.PARAM01").unwrap());
        let mailbox_failed = Err(MailboxError::InfoErrorWithoutCode.into());
        assert!(parameter_confirmed(mailbox_failed, "VENDOR.PARAM01").is_err(), "not the slave's answer: an error");
    }
}
