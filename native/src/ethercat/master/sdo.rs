//! CoE SDO client: upload (read) and download (write) of object dictionary entries, expedited
//! (up to 4 bytes in the request or reply), normal (the whole value in one mailbox) and
//! segmented (what the mailbox cannot hold, in segments with an alternating toggle bit).
//! Aborts come back as [`Error::SdoAbort`] with the code's name.

use crate::error::{Error, MailboxError, Result, SettingError};
use crate::ethercat::coe::{self, CoeService, SdoAbortCode, SdoRequest, SdoResponse, SDO_LEN, SDO_OFFSET};
use crate::ethercat::master::Master;

impl Master {
    /// Sends one CoE message built by `write` and returns the slave's reply message.
    pub(crate) fn coe_transaction(&mut self, position: u16, write: impl FnOnce(&mut [u8]) -> usize) -> Result<Vec<u8>> {
        let mut message = vec![0u8; self.mailbox_out_len(position)?];
        let len = write(&mut message);
        self.mailbox_flush(position)?;
        self.mailbox_send(position, &mut message[..len], self.mailbox_timeout)?;
        self.mailbox_receive(position, self.mailbox_timeout)
    }

    fn mailbox_out_len(&self, position: u16) -> Result<usize> {
        let slave = self.slave(position)?;
        match &slave.mailbox {
            Some(mb) if mb.has_coe() => Ok(mb.out_len as usize),
            _ => Err(MailboxError::NoCoe { slave: position }.into()),
        }
    }

    /// One SDO request and its response, decoded by `handle`.
    fn sdo_exchange<T>(
        &mut self,
        position: u16,
        request: &SdoRequest<'_>,
        handle: impl FnOnce(SdoResponse<'_>) -> Result<T>,
    ) -> Result<T> {
        let reply = self.coe_transaction(position, |out| coe::write_sdo_request(out, 0, request))?;
        let body = body_of_service(position, &reply, CoeService::SdoResponse, "an SDO request")?;
        handle(SdoResponse::decode(body)?)
    }

    /// Aborts a transfer the slave got wrong and returns the error that says why.
    fn sdo_abort(&mut self, position: u16, index: u16, subindex: u8, code: SdoAbortCode) -> Error {
        let request = SdoRequest::Abort { index, subindex, code };
        let mut message = [0u8; SDO_OFFSET + SDO_LEN];
        let len = coe::write_sdo_request(&mut message, 0, &request);
        // The abort is a courtesy to the slave; the error to report is the one found here.
        let _ = self.mailbox_send(position, &mut message[..len], self.mailbox_timeout);
        Error::sdo_abort(index, subindex, code)
    }

    /// Reads `index:subindex` of the slave at `position`.
    pub(super) fn sdo_read(&mut self, position: u16, index: u16, subindex: u8) -> Result<Vec<u8>> {
        let request = SdoRequest::Upload { index, subindex, complete_access: false };
        let (mut value, complete_size) = self.sdo_exchange(position, &request, |response| match response {
            SdoResponse::UploadExpedited { index: i, subindex: s, data } if (i, s) == (index, subindex) => {
                Ok((data.to_vec(), data.len()))
            }
            SdoResponse::UploadNormal { index: i, subindex: s, complete_size, data } if (i, s) == (index, subindex) => {
                let size = complete_size as usize;
                Ok((data[..data.len().min(size)].to_vec(), size))
            }
            other => Err(unexpected(position, index, subindex, "upload", &other)),
        })?;
        let mut toggle = false;
        while value.len() < complete_size {
            let segment =
                self.sdo_exchange(position, &SdoRequest::UploadSegment { toggle }, |response| match response {
                    SdoResponse::UploadSegment { toggle: t, last, data } => Ok(Some((t, last, data.to_vec()))),
                    SdoResponse::Abort { code, .. } => Err(Error::sdo_abort(index, subindex, code)),
                    _ => Ok(None),
                })?;
            let Some((t, last, data)) = segment else {
                return Err(self.sdo_abort(position, index, subindex, SdoAbortCode::BAD_COMMAND));
            };
            if t != toggle {
                return Err(self.sdo_abort(position, index, subindex, SdoAbortCode::TOGGLE_BIT));
            }
            if data.is_empty() && !last {
                // A segment must carry data; an empty one would never end the transfer.
                return Err(self.sdo_abort(position, index, subindex, SdoAbortCode::LENGTH_TOO_LOW));
            }
            value.extend_from_slice(&data);
            toggle = !toggle;
            if last {
                break;
            }
        }
        if value.len() != complete_size {
            return Err(MailboxError::UploadSize {
                slave: position,
                index,
                subindex,
                announced: complete_size,
                carried: value.len(),
            }
            .into());
        }
        Ok(value)
    }

    /// Writes `data` to `index:subindex` of the slave at `position`.
    pub(super) fn sdo_write(&mut self, position: u16, index: u16, subindex: u8, data: &[u8]) -> Result<()> {
        let room = self.mailbox_out_len(position)? - SDO_OFFSET;
        let accepted = |position| {
            move |response: SdoResponse<'_>| match response {
                SdoResponse::Download { index: i, subindex: s } if (i, s) == (index, subindex) => Ok(()),
                other => Err(unexpected(position, index, subindex, "download", &other)),
            }
        };
        if data.is_empty() {
            return Err(SettingError::EmptySdoWrite { index, subindex }.into());
        }
        if data.len() <= 4 {
            let request = SdoRequest::DownloadExpedited { index, subindex, complete_access: false, data };
            return self.sdo_exchange(position, &request, accepted(position));
        }
        let first = data.len().min(room - SDO_LEN);
        let request = SdoRequest::DownloadNormal {
            index,
            subindex,
            complete_access: false,
            complete_size: data.len() as u32,
            data: &data[..first],
        };
        self.sdo_exchange(position, &request, accepted(position))?;
        let mut toggle = false;
        for chunk_start in (first..data.len()).step_by(room - 1) {
            let chunk = &data[chunk_start..data.len().min(chunk_start + room - 1)];
            let last = chunk_start + chunk.len() == data.len();
            let request = SdoRequest::DownloadSegment { toggle, last, data: chunk };
            let answered = self.sdo_exchange(position, &request, |response| match response {
                SdoResponse::DownloadSegment { toggle: t } => Ok(Some(t)),
                SdoResponse::Abort { code, .. } => Err(Error::sdo_abort(index, subindex, code)),
                _ => Ok(None),
            })?;
            match answered {
                Some(t) if t == toggle => toggle = !toggle,
                Some(_) => return Err(self.sdo_abort(position, index, subindex, SdoAbortCode::TOGGLE_BIT)),
                None => return Err(self.sdo_abort(position, index, subindex, SdoAbortCode::BAD_COMMAND)),
            }
        }
        Ok(())
    }
}

/// The body of the CoE reply `reply` of the slave at `position` to `request`, which only
/// `expected` answers; any other service is an error naming both.
pub(super) fn body_of_service<'a>(
    position: u16,
    reply: &'a [u8],
    expected: CoeService,
    request: &'static str,
) -> Result<&'a [u8]> {
    let (_, coe_header, body) = coe::split_message(reply)?;
    if coe_header.service != expected {
        return Err(MailboxError::UnexpectedService {
            slave: position,
            request,
            got: coe_header.service.name(),
            expected: expected.name(),
        }
        .into());
    }
    Ok(body)
}

/// The error for a response that does not answer the request: an abort by name, or a
/// description of what came instead.
fn unexpected(position: u16, index: u16, subindex: u8, what: &'static str, response: &SdoResponse<'_>) -> Error {
    match *response {
        SdoResponse::Abort { code, .. } => Error::sdo_abort(index, subindex, code),
        ref other => MailboxError::UnexpectedResponse {
            slave: position,
            transfer: what,
            index,
            subindex,
            response: format!("{other:?}"),
        }
        .into(),
    }
}
