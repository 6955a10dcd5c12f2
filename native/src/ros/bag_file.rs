//! One MCAP file of a rosbag2 bag, written with the `mcap` crate, for a recorder that hands it
//! tens of thousands of messages a second (every cycle of every drive) without spending a core
//! on the container format.
//!
//! Chunks close only when [`BagFile::flush`] says so, so that the recorder decides when what it
//! holds is safe on disk; the summary (statistics, indexes, CRCs) is written by
//! [`BagFile::finish`].

use std::collections::BTreeMap;
use std::fs::File;
use std::io;
use std::path::Path;

use mcap::records::{MessageHeader, Metadata};
use mcap::{Compression, McapError, WriteOptions, Writer};

/// An open MCAP file being written.
pub struct BagFile {
    writer: Writer<File>,
    // A second handle on the same file, for its size and fsync while the writer holds the first.
    file: File,
    sequence: u32,
}

impl BagFile {
    /// Creates `path`, its chunks compressed by `compression` (`None`: not compressed), and
    /// writes the header of the `profile` (e.g. "ros2") with `library`.
    pub fn create(
        path: &Path,
        compression: Option<Compression>,
        profile: &str,
        library: &str,
    ) -> Result<BagFile, McapError> {
        let file = File::create(path)?;
        let handle = file.try_clone()?;
        let writer = WriteOptions::new()
            .compression(compression)
            .profile(profile)
            .library(library)
            .chunk_size(None)
            // Each chunk is built in memory and written whole when closed, never streamed with a
            // length patched in later: a killed recorder leaves a file that ends after its last
            // closed chunk, which readers and reindex take as it is.
            .disable_seeking(true)
            .create(file)?;
        Ok(BagFile { writer, file: handle, sequence: 0 })
    }

    /// Adds a schema; its id.
    pub fn add_schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> Result<u16, McapError> {
        self.writer.add_schema(name, encoding, data)
    }

    /// Adds a channel of `schema_id`; its id.
    pub fn add_channel(
        &mut self,
        schema_id: u16,
        topic: &str,
        message_encoding: &str,
        metadata: &BTreeMap<String, String>,
    ) -> Result<u16, McapError> {
        self.writer.add_channel(schema_id, topic, message_encoding, metadata)
    }

    /// Adds one message to the open chunk, logged and published at `time_ns`.
    pub fn add_message(&mut self, channel_id: u16, time_ns: u64, data: &[u8]) -> Result<(), McapError> {
        self.sequence = self.sequence.wrapping_add(1);
        let header = MessageHeader { channel_id, sequence: self.sequence, log_time: time_ns, publish_time: time_ns };
        self.writer.write_to_known_channel(&header, data)
    }

    /// Closes the open chunk (compressed) and writes it to the file.
    pub fn flush(&mut self) -> Result<(), McapError> {
        self.writer.flush()
    }

    /// The file's size so far: what the closed chunks and the records before them take.
    pub fn size(&self) -> io::Result<u64> {
        Ok(self.file.metadata()?.len())
    }

    /// Waits until what was written is on the disk.
    pub fn sync(&self) -> io::Result<()> {
        self.file.sync_all()
    }

    /// Writes a metadata record `name` of `entries`, then the summary and footer, and syncs.
    pub fn finish(&mut self, name: &str, entries: BTreeMap<String, String>) -> Result<(), McapError> {
        self.writer.write_metadata(&Metadata { name: name.to_owned(), metadata: entries })?;
        self.writer.finish()?;
        Ok(self.sync()?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mcap::MessageStream;

    #[test]
    fn messages_come_back_from_the_crates_reader_in_order_with_their_channel() {
        let dir = std::env::temp_dir().join(format!("akd_bag_file_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a.mcap");
        let mut bag = BagFile::create(&path, Some(Compression::Zstd), "ros2", "test").unwrap();
        let schema = bag.add_schema("std_msgs/msg/UInt8", "ros2msg", b"uint8 data").unwrap();
        let channel = bag.add_channel(schema, "/a", "cdr", &BTreeMap::new()).unwrap();
        for i in 0..100u8 {
            bag.add_message(channel, 1000 + i as u64, &[0, 1, 0, 0, i]).unwrap();
            if i == 49 {
                bag.flush().unwrap();
                assert!(bag.size().unwrap() > 0);
            }
        }
        bag.finish("rosbag2", BTreeMap::from([("ROS_DISTRO".to_owned(), "jazzy".to_owned())])).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let read: Vec<_> = MessageStream::new(&bytes).unwrap().map(Result::unwrap).collect();
        assert_eq!(read.len(), 100);
        assert!(read
            .iter()
            .enumerate()
            .all(|(i, m)| m.log_time == 1000 + i as u64 && m.channel.topic == "/a" && m.data[4] == i as u8));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
