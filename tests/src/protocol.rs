//! Protocol 2.0 facts the protocol tests share, written from the ROBOTIS e-Manual rather
//! than taken from the codec: the instructions a client sends.

use softcbf::protocol::Instruction;

/// Every instruction of an instruction packet (all but Status), in the e-Manual's order.
pub const INSTRUCTIONS: [Instruction; 12] = [
    Instruction::Ping,
    Instruction::Read,
    Instruction::Write,
    Instruction::RegWrite,
    Instruction::Action,
    Instruction::FactoryReset,
    Instruction::Reboot,
    Instruction::Clear,
    Instruction::SyncRead,
    Instruction::SyncWrite,
    Instruction::BulkRead,
    Instruction::BulkWrite,
];
