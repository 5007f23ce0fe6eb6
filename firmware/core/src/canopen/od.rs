//! The object dictionary: which (index, sub-index) pairs exist, their names, data types and
//! access, all derived from constants here and from the one parameter table [`PARAMS`].
//!
//! The node ([`super::node`]) reads and writes values; this module only describes. The EDS
//! generator of the host tool walks [`indices`] and [`sub_info`], so the EDS can never list an
//! object the node does not serve, or miss one it does.
//!
//! Layout (CiA 301 communication area, then manufacturer objects from 0x2000):
//! - `0x1200`/`0x1201`: the SDO server channels, the default one and a second one a master
//!   configures (its COB-IDs are "not valid" until written), each with its own transfer;
//! - `0x2000 + i`: scalar parameter `PARAMS[i]` (`friction_a` = 0x2000 …), REAL32, read/write
//!   into the **staged** set; the range and safety flag come from the table;
//! - `0x2100` gravity table shape (record of U8, sub 11: the table is the model's residual),
//!   `0x2101..=0x2103` grid/torque/sigma as DOMAINs of little-endian f32 (segmented SDO);
//! - `0x2104` gravity series term count (U8), `0x2105` its terms as a DOMAIN of 12-byte
//!   records (f32 amplitude, f32 phase, 4 × i8 multipliers; see [`crate::series`]);
//! - `0x2200` write 0: discard the staged changes (1, a commit that names no set, is refused),
//!   `0x2201` last commit error, `0x2202` clear faults, `0x2203` staged ≠ active, `0x2204` the
//!   CRC-32 of the set in force and of the staged set, `0x2205` commit: write the CRC-32 of the
//!   set meant, the staged set is checked and swapped in whole only if it is that set;
//! - `0x2300` joint state (PDO-mappable scaled integers), `0x2301` the same state in REAL32 (the
//!   CAN FD TPDO3: a master needs no scale), `0x2310` host command, `0x2311` the other joints'
//!   angles (inputs of a multi-joint gravity table).

use super::sdo::Abort;
use crate::params::{ParamId, PARAMS, PARAM_COUNT};

/// CiA 301 data types used here (the EDS `DataType` numbers).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u16)]
pub enum DataType {
    Boolean = 0x0001,
    Integer16 = 0x0003,
    Integer32 = 0x0004,
    Unsigned8 = 0x0005,
    Unsigned16 = 0x0006,
    Unsigned32 = 0x0007,
    Real32 = 0x0008,
    VisibleString = 0x0009,
    Domain = 0x000F,
}

impl DataType {
    /// Size in bytes of a fixed-size type; `None` for strings and domains.
    pub const fn size(self) -> Option<usize> {
        match self {
            DataType::Boolean | DataType::Unsigned8 => Some(1),
            DataType::Integer16 | DataType::Unsigned16 => Some(2),
            DataType::Integer32 | DataType::Unsigned32 | DataType::Real32 => Some(4),
            DataType::VisibleString | DataType::Domain => None,
        }
    }
}

/// Access type as written in the EDS.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Access {
    Const,
    Ro,
    Wo,
    Rw,
}

impl Access {
    pub const fn readable(self) -> bool {
        !matches!(self, Access::Wo)
    }
    pub const fn writable(self) -> bool {
        matches!(self, Access::Wo | Access::Rw)
    }
    /// EDS spelling.
    pub const fn eds(self) -> &'static str {
        match self {
            Access::Const => "const",
            Access::Ro => "ro",
            Access::Wo => "wo",
            Access::Rw => "rw",
        }
    }
}

/// Object code of an index (EDS `ObjectType`: 7 VAR, 8 ARRAY, 9 RECORD).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ObjectKind {
    Var,
    Array,
    Record,
}

/// What a sub-index is, for the node's read/write dispatch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Key {
    DeviceType,
    ErrorRegister,
    DeviceName,
    SoftwareVersion,
    /// sub-index 0 of an array/record: the highest sub-index, constant
    Count(u8),
    StoreAll,
    RestoreAll,
    ConsumerHeartbeat,
    ProducerHeartbeat,
    /// 0x1003 sub 0: number of errors in the history (write 0 to clear it)
    ErrorHistoryCount,
    /// 0x1003 sub 1..=8: the newest error first
    ErrorHistory(u8),
    /// 0x1005: COB-ID of the SYNC the node consumes
    SyncCobId,
    /// 0x1014: COB-ID of the node's EMCY
    EmcyCobId,
    /// 0x1029 sub 1: what a communication error does to the NMT state
    ErrorBehaviour,
    /// 1 vendor, 2 product, 3 revision, 4 serial
    Identity(u8),
    /// SDO server parameter (channel 0 = 0x1200, 1 = 0x1201; sub 1 COB-ID client → server,
    /// 2 server → client, 3 the client's node id)
    SdoServer(u8, u8),
    RpdoCobId(u8),
    RpdoType(u8),
    /// (pdo, sub 1..)
    RpdoMap(u8, u8),
    /// sub 0 of a PDO mapping (tx, pdo): the number of entries in force, written to change it
    MapCount(bool, u8),
    TpdoCobId(u8),
    TpdoType(u8),
    TpdoInhibit(u8),
    TpdoEvent(u8),
    TpdoMap(u8, u8),
    Param(ParamId),
    /// sub-index of 0x2100
    TableShape(u8),
    TableGrid,
    TableTorque,
    TableSigma,
    /// 0x2104
    SeriesCount,
    /// 0x2105
    SeriesTerms,
    Commit,
    ErrorCode,
    ErrorParam,
    ErrorMessage,
    ClearFaults,
    Pending,
    /// 0x2204 sub 1: CRC of the set in force ([`crate::store::set_crc`])
    ActiveCrc,
    /// 0x2204 sub 2: CRC of the staged set
    StagedCrc,
    /// 0x2205: commit the staged set if its CRC is the one written
    CommitCrc,
    /// sub-index of 0x2300
    JointState(u8),
    /// sub-index of 0x2301
    JointStateF32(u8),
    AssistCmd,
    /// 1..=3
    OtherAngle(u8),
}

/// Everything known about one sub-index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubInfo {
    pub index: u16,
    pub sub: u8,
    pub name: &'static str,
    pub dtype: DataType,
    pub access: Access,
    /// may be mapped into a PDO
    pub pdo: bool,
    /// default value is `$NODEID + value` (COB-IDs)
    pub node_relative: bool,
    /// limits for the EDS (parameters only)
    pub limits: Option<(f32, f32)>,
    pub key: Key,
}

/// One index of the dictionary.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectInfo {
    pub index: u16,
    pub name: &'static str,
    pub kind: ObjectKind,
    /// sub-indices that exist (sub 0 included for arrays/records)
    pub subs: &'static [u8],
}

pub const DEVICE_TYPE: u16 = 0x1000;
pub const ERROR_REGISTER: u16 = 0x1001;
/// pre-defined error field: the last EMCY codes, newest first
pub const ERROR_HISTORY: u16 = 0x1003;
pub const COB_ID_SYNC: u16 = 0x1005;
pub const DEVICE_NAME: u16 = 0x1008;
pub const SOFTWARE_VERSION: u16 = 0x100A;
pub const STORE_PARAMETERS: u16 = 0x1010;
pub const RESTORE_DEFAULTS: u16 = 0x1011;
pub const CONSUMER_HEARTBEAT: u16 = 0x1016;
pub const PRODUCER_HEARTBEAT: u16 = 0x1017;
pub const IDENTITY: u16 = 0x1018;
pub const COB_ID_EMCY: u16 = 0x1014;
pub const ERROR_BEHAVIOUR: u16 = 0x1029;
/// SDO server parameter of the default channel (0x600/0x580 + id, read-only)
pub const SDO_SERVER1: u16 = 0x1200;
/// the second SDO server channel: COB-IDs and client set by the master, not valid until then
pub const SDO_SERVER2: u16 = 0x1201;
/// Entries the error history keeps.
pub const ERROR_HISTORY_LEN: usize = 8;
pub const RPDO_COMM: u16 = 0x1400;
pub const RPDO_MAP: u16 = 0x1600;
pub const TPDO_COMM: u16 = 0x1800;
pub const TPDO_MAP: u16 = 0x1A00;
/// First scalar-parameter object; parameter `i` lives at `PARAM_BASE + i`.
pub const PARAM_BASE: u16 = 0x2000;
pub const TABLE_SHAPE: u16 = 0x2100;
pub const TABLE_GRID: u16 = 0x2101;
pub const TABLE_TORQUE: u16 = 0x2102;
pub const TABLE_SIGMA: u16 = 0x2103;
pub const SERIES_COUNT: u16 = 0x2104;
pub const SERIES_TERMS: u16 = 0x2105;
pub const COMMIT: u16 = 0x2200;
pub const COMMIT_ERROR: u16 = 0x2201;
pub const CLEAR_FAULTS: u16 = 0x2202;
pub const PENDING: u16 = 0x2203;
/// sub 1: CRC-32 of the set in force, sub 2: of the staged set
pub const PARAMS_CRC: u16 = 0x2204;
/// write the staged set's CRC-32: commits it only if it is that set (a commit that names what
/// it commits, so another master's writes in between can never go live with it)
pub const COMMIT_CRC: u16 = 0x2205;
pub const JOINT_STATE: u16 = 0x2300;
/// the joint state in REAL32 (SI units), mapped into the CAN FD TPDO3
pub const JOINT_STATE_F32: u16 = 0x2301;
pub const HOST_COMMAND: u16 = 0x2310;
pub const OTHER_ANGLES: u16 = 0x2311;

// Parameter objects run from PARAM_BASE up to the gravity table's objects at 0x2100.
const _: () = assert!(PARAM_COUNT <= (TABLE_SHAPE - PARAM_BASE) as usize);

/// Number of RPDOs: 1 = host command, 2..=4 = other joints' angles.
pub const RPDO_COUNT: u8 = 4;
/// Number of TPDOs: 1 = q, q̇, τ, faults; 2 = q̈, measured τ, temperature, gain (classic CAN,
/// 8 bytes each); 3 = the whole state in REAL32, 32 bytes (CAN FD only: [`TPDO_FD`]).
pub const TPDO_COUNT: u8 = 3;
/// The 0-based number of the CAN FD TPDO (TPDO3, COB-ID 0x380 + node): valid by default on a
/// node configured for FD (whose classic TPDO1/2 start invalid), invalid on a classic node,
/// which refuses to validate it (its 32 bytes exceed a classic frame: abort 0x06040042).
pub const TPDO_FD: u8 = 2;
/// Most mapping entries a PDO holds here (CiA 301 allows up to 64; 16 REAL32 fill an FD frame).
pub const MAP_MAX: usize = 16;

/// "save" in little-endian ASCII, the CiA 301 signature for 0x1010.
pub const SAVE_SIGNATURE: u32 = 0x6576_6173;
/// "load", the CiA 301 signature for 0x1011.
pub const LOAD_SIGNATURE: u32 = 0x6461_6F6C;

/// Sub-indices of 0x2300 (joint state), mapped into the TPDOs.
pub const JS_Q: u8 = 1;
pub const JS_QD: u8 = 2;
pub const JS_TAU: u8 = 3;
pub const JS_FAULTS: u8 = 4;
pub const JS_QDD: u8 = 5;
pub const JS_TAU_MEAS: u8 = 6;
pub const JS_TEMP: u8 = 7;
pub const JS_GAIN: u8 = 8;

/// Sub-indices of 0x2301 (joint state, REAL32; q … temperature in the SI units of 0x2300).
pub const JF_Q: u8 = 1;
pub const JF_QD: u8 = 2;
pub const JF_QDD: u8 = 3;
pub const JF_TAU: u8 = 4;
pub const JF_TAU_MEAS: u8 = 5;
/// torque command at the motor, N·m (τ / gear ratio)
pub const JF_U_MOTOR: u8 = 6;
pub const JF_TEMP: u8 = 7;
/// U8: 0 torque off, 1 assist (operational)
pub const JF_MODE: u8 = 8;
/// safety output gain, 0..=1
pub const JF_GAIN: u8 = 9;
/// the host's assist command as the node holds it, N·m
pub const JF_ASSIST: u8 = 10;
const JOINT_STATE_F32_NAMES: [&str; 10] =
    ["q", "qd", "qdd", "tau_cmd", "tau_measured", "u_motor", "temperature", "mode", "gain", "assist_cmd"];
const JOINT_STATE_NAMES: [&str; 8] =
    ["q", "qd", "tau_cmd", "faults", "qdd", "tau_measured", "temperature", "gain_permille"];
const SHAPE_NAMES: [&str; 11] = [
    "n_axes",
    "axis_source_0",
    "axis_source_1",
    "axis_source_2",
    "axis_source_3",
    "points_0",
    "points_1",
    "points_2",
    "points_3",
    "has_sigma",
    "residual",
];
const IDENTITY_NAMES: [&str; 4] = ["vendor_id", "product_code", "revision_number", "serial_number"];
const MAP_NAMES: [&str; MAP_MAX] = [
    "mapped_object_1",
    "mapped_object_2",
    "mapped_object_3",
    "mapped_object_4",
    "mapped_object_5",
    "mapped_object_6",
    "mapped_object_7",
    "mapped_object_8",
    "mapped_object_9",
    "mapped_object_10",
    "mapped_object_11",
    "mapped_object_12",
    "mapped_object_13",
    "mapped_object_14",
    "mapped_object_15",
    "mapped_object_16",
];
const OTHER_NAMES: [&str; 3] = ["other_angle_1", "other_angle_2", "other_angle_3"];
const RPDO_NAMES: [&str; 4] =
    ["rpdo1_communication", "rpdo2_communication", "rpdo3_communication", "rpdo4_communication"];
const RPDO_MAP_NAMES: [&str; 4] = ["rpdo1_mapping", "rpdo2_mapping", "rpdo3_mapping", "rpdo4_mapping"];
const TPDO_NAMES: [&str; 3] = ["tpdo1_communication", "tpdo2_communication", "tpdo3_communication"];
const TPDO_MAP_NAMES: [&str; 3] = ["tpdo1_mapping", "tpdo2_mapping", "tpdo3_mapping"];

/// Default mapping entries (index << 16 | sub << 8 | bits) of TPDO `n` (0-based); a master
/// may remap (0x1A00.., [`super::pdo_map`]).
pub fn tpdo_mapping(n: u8) -> &'static [u32] {
    TPDO_DEFAULTS.get(n as usize).copied().unwrap_or(&[])
}

/// The default TPDO mappings, TPDO1 first.
pub const TPDO_DEFAULTS: [&[u32]; TPDO_COUNT as usize] = {
    const T1: [u32; 4] = [
        map_entry(JOINT_STATE, JS_Q, 16),
        map_entry(JOINT_STATE, JS_QD, 16),
        map_entry(JOINT_STATE, JS_TAU, 16),
        map_entry(JOINT_STATE, JS_FAULTS, 16),
    ];
    const T2: [u32; 4] = [
        map_entry(JOINT_STATE, JS_QDD, 16),
        map_entry(JOINT_STATE, JS_TAU_MEAS, 16),
        map_entry(JOINT_STATE, JS_TEMP, 16),
        map_entry(JOINT_STATE, JS_GAIN, 16),
    ];
    // CAN FD: the whole state in one 32-byte frame (7 × REAL32, faults, mode, error register).
    // Not 64 bytes: at 1/5 Mbit/s a 64-byte frame takes ≥ 140 µs, so six joints at 1 kHz
    // would load the bus ≥ 84 %; 32 bytes take ≈ 90 µs (docs/canopen.md, bus budget).
    const T3: [u32; 10] = [
        map_entry(JOINT_STATE_F32, JF_Q, 32),
        map_entry(JOINT_STATE_F32, JF_QD, 32),
        map_entry(JOINT_STATE_F32, JF_QDD, 32),
        map_entry(JOINT_STATE_F32, JF_TAU, 32),
        map_entry(JOINT_STATE_F32, JF_TAU_MEAS, 32),
        map_entry(JOINT_STATE_F32, JF_U_MOTOR, 32),
        map_entry(JOINT_STATE_F32, JF_TEMP, 32),
        map_entry(JOINT_STATE, JS_FAULTS, 16),
        map_entry(JOINT_STATE_F32, JF_MODE, 8),
        map_entry(ERROR_REGISTER, 0, 8),
    ];
    [&T1, &T2, &T3]
};

/// CiA 301 dummy mapping entries: the data types UNSIGNED16 (0x0006) and UNSIGNED32 (0x0007)
/// as mapped objects skip that many bits of a received PDO.
pub const DUMMY_U16: u32 = map_entry(0x0006, 0, 16);
pub const DUMMY_U32: u32 = map_entry(0x0007, 0, 32);

/// COB-ID of the host's shared command frame on a CAN FD bus: one FD frame with every
/// joint's 16-bit assist command, joint `id` at bytes `2(id − 1)..2id` (ids 1..=[`SHARED_CMD_IDS`]).
/// 0x200 is RPDO1's base with node id 0, which no node has.
pub const SHARED_CMD_COB: u16 = 0x200;
/// Node ids with a slot in the shared command frame: 1..=31 (id 32's slot, bytes 62..64,
/// would need 17 mapping entries: 15 UNSIGNED32 and one UNSIGNED16 dummy, then its value).
pub const SHARED_CMD_IDS: u8 = 31;

/// RPDO1's mapping on an FD node with id `node_id`: dummies up to its slot in the shared
/// command frame, then the assist command (`None` when the id has no slot). Written into
/// `out`, the number of entries returned.
#[inline(never)]
pub fn shared_cmd_mapping(node_id: u8, out: &mut [u32; MAP_MAX]) -> Option<usize> {
    if !(1..=SHARED_CMD_IDS).contains(&node_id) {
        return None;
    }
    let skip = usize::from(node_id - 1); // 16-bit slots before ours
                                         // a loop bounded by the id, not by MAP_MAX: unrolled 16 times it cost 0.9 KiB of flash
    let mut k = 0;
    while k < skip / 2 {
        *out.get_mut(k)? = DUMMY_U32;
        k += 1;
    }
    if skip % 2 == 1 {
        *out.get_mut(k)? = DUMMY_U16;
        k += 1;
    }
    *out.get_mut(k)? = map_entry(HOST_COMMAND, 1, 16);
    Some(k + 1)
}

/// Mapping of RPDO `n` (0-based): RPDO1 carries the host's assist command; RPDO2..4 each take
/// the first 16 bits of a frame — point their COB-ID at another joint's TPDO1 (0x180 + id)
/// and its `q` lands in the matching `others` slot. Extra bytes of a longer frame are ignored
/// (CiA 301 allows a received PDO longer than its mapping).
pub fn rpdo_mapping(n: u8) -> &'static [u32] {
    RPDO_DEFAULTS.get(n as usize).copied().unwrap_or(&[])
}

/// The default RPDO mappings, RPDO1 first.
pub const RPDO_DEFAULTS: [&[u32]; RPDO_COUNT as usize] = {
    const R1: [u32; 1] = [map_entry(HOST_COMMAND, 1, 16)];
    const R2: [u32; 1] = [map_entry(OTHER_ANGLES, 1, 16)];
    const R3: [u32; 1] = [map_entry(OTHER_ANGLES, 2, 16)];
    const R4: [u32; 1] = [map_entry(OTHER_ANGLES, 3, 16)];
    [&R1, &R2, &R3, &R4]
};

const fn map_entry(index: u16, sub: u8, bits: u8) -> u32 {
    ((index as u32) << 16) | ((sub as u32) << 8) | bits as u32
}

/// Every index of the dictionary, ascending.
pub fn indices() -> impl Iterator<Item = u16> {
    const LOW: [u16; 15] = [
        DEVICE_TYPE,
        ERROR_REGISTER,
        ERROR_HISTORY,
        COB_ID_SYNC,
        DEVICE_NAME,
        SOFTWARE_VERSION,
        STORE_PARAMETERS,
        RESTORE_DEFAULTS,
        COB_ID_EMCY,
        CONSUMER_HEARTBEAT,
        PRODUCER_HEARTBEAT,
        IDENTITY,
        ERROR_BEHAVIOUR,
        SDO_SERVER1,
        SDO_SERVER2,
    ];
    const HIGH: [u16; 16] = [
        TABLE_SHAPE,
        TABLE_GRID,
        TABLE_TORQUE,
        TABLE_SIGMA,
        SERIES_COUNT,
        SERIES_TERMS,
        COMMIT,
        COMMIT_ERROR,
        CLEAR_FAULTS,
        PENDING,
        PARAMS_CRC,
        COMMIT_CRC,
        JOINT_STATE,
        JOINT_STATE_F32,
        HOST_COMMAND,
        OTHER_ANGLES,
    ];
    LOW.into_iter()
        .chain((0..RPDO_COUNT as u16).map(|n| RPDO_COMM + n))
        .chain((0..RPDO_COUNT as u16).map(|n| RPDO_MAP + n))
        .chain((0..TPDO_COUNT as u16).map(|n| TPDO_COMM + n))
        .chain((0..TPDO_COUNT as u16).map(|n| TPDO_MAP + n))
        .chain((0..PARAM_COUNT as u16).map(|i| PARAM_BASE + i))
        .chain(HIGH)
}

const SUB0: &[u8] = &[0];
const ERROR_HISTORY_NAMES: [&str; ERROR_HISTORY_LEN] = [
    "standard_error_field_1",
    "standard_error_field_2",
    "standard_error_field_3",
    "standard_error_field_4",
    "standard_error_field_5",
    "standard_error_field_6",
    "standard_error_field_7",
    "standard_error_field_8",
];
const SUBS_1: &[u8] = &[0, 1];
const SUBS_2: &[u8] = &[0, 1, 2];
const SUBS_3: &[u8] = &[0, 1, 2, 3];
const SUBS_4: &[u8] = &[0, 1, 2, 3, 4];
const SUBS_8: &[u8] = &[0, 1, 2, 3, 4, 5, 6, 7, 8];
const SUBS_10: &[u8] = &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10];
const SUBS_11: &[u8] = &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11];
const SUBS_16: &[u8] = &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16];
const TPDO_COMM_SUBS: &[u8] = &[0, 1, 2, 3, 5];

/// The object at `index`, if the dictionary has it.
pub fn object_info(index: u16) -> Option<ObjectInfo> {
    use ObjectKind::*;
    let o = |name, kind, subs| Some(ObjectInfo { index, name, kind, subs });
    match index {
        DEVICE_TYPE => o("device_type", Var, SUB0),
        ERROR_REGISTER => o("error_register", Var, SUB0),
        ERROR_HISTORY => o("pre_defined_error_field", Array, SUBS_8),
        COB_ID_SYNC => o("cob_id_sync", Var, SUB0),
        COB_ID_EMCY => o("cob_id_emcy", Var, SUB0),
        ERROR_BEHAVIOUR => o("error_behaviour", Array, SUBS_1),
        DEVICE_NAME => o("manufacturer_device_name", Var, SUB0),
        SOFTWARE_VERSION => o("manufacturer_software_version", Var, SUB0),
        STORE_PARAMETERS => o("store_parameters", Array, SUBS_1),
        RESTORE_DEFAULTS => o("restore_default_parameters", Array, SUBS_1),
        CONSUMER_HEARTBEAT => o("consumer_heartbeat_time", Array, SUBS_1),
        PRODUCER_HEARTBEAT => o("producer_heartbeat_time", Var, SUB0),
        IDENTITY => o("identity", Record, SUBS_4),
        SDO_SERVER1 => o("sdo_server_1", Record, SUBS_2),
        SDO_SERVER2 => o("sdo_server_2", Record, SUBS_3),
        i if (RPDO_COMM..RPDO_COMM + RPDO_COUNT as u16).contains(&i) => {
            o(RPDO_NAMES.get((i - RPDO_COMM) as usize).copied().unwrap_or(""), Record, SUBS_2)
        }
        i if (RPDO_MAP..RPDO_MAP + RPDO_COUNT as u16).contains(&i) => {
            // writable mappings: every entry a PDO may hold is listed, sub 0 says how many count
            o(RPDO_MAP_NAMES.get((i - RPDO_MAP) as usize).copied().unwrap_or(""), Record, SUBS_16)
        }
        i if (TPDO_COMM..TPDO_COMM + TPDO_COUNT as u16).contains(&i) => {
            o(TPDO_NAMES.get((i - TPDO_COMM) as usize).copied().unwrap_or(""), Record, TPDO_COMM_SUBS)
        }
        i if (TPDO_MAP..TPDO_MAP + TPDO_COUNT as u16).contains(&i) => {
            o(TPDO_MAP_NAMES.get((i - TPDO_MAP) as usize).copied().unwrap_or(""), Record, SUBS_16)
        }
        i if (PARAM_BASE..PARAM_BASE + PARAM_COUNT as u16).contains(&i) => {
            let d = PARAMS.get((i - PARAM_BASE) as usize)?;
            o(d.name, Var, SUB0)
        }
        TABLE_SHAPE => o("gravity_table_shape", Record, SUBS_11),
        TABLE_GRID => o("gravity_table_grid", Var, SUB0),
        TABLE_TORQUE => o("gravity_table_torque", Var, SUB0),
        TABLE_SIGMA => o("gravity_table_sigma", Var, SUB0),
        SERIES_COUNT => o("gravity_series_count", Var, SUB0),
        SERIES_TERMS => o("gravity_series_terms", Var, SUB0),
        COMMIT => o("params_commit", Var, SUB0),
        COMMIT_ERROR => o("params_commit_error", Record, SUBS_3),
        CLEAR_FAULTS => o("clear_faults", Var, SUB0),
        PENDING => o("params_pending", Var, SUB0),
        PARAMS_CRC => o("params_crc", Record, SUBS_2),
        COMMIT_CRC => o("params_commit_crc", Var, SUB0),
        JOINT_STATE => o("joint_state", Record, SUBS_8),
        JOINT_STATE_F32 => o("joint_state_real32", Record, SUBS_10),
        HOST_COMMAND => o("host_command", Record, SUBS_1),
        OTHER_ANGLES => o("other_joint_angles", Array, SUBS_3),
        _ => None,
    }
}

/// The sub-index `sub` of `index`, or the abort a master gets for asking: object missing
/// (0x06020000) or sub-index missing (0x06090011).
pub fn sub_info(index: u16, sub: u8) -> Result<SubInfo, Abort> {
    use Access::*;
    use DataType::*;
    let obj = object_info(index).ok_or(Abort::NoObject)?;
    if !obj.subs.contains(&sub) {
        return Err(Abort::NoSubIndex);
    }
    let mk = |name, dtype, access, key| SubInfo {
        index,
        sub,
        name,
        dtype,
        access,
        pdo: false,
        node_relative: false,
        limits: None,
        key,
    };
    let highest = obj.subs.last().copied().unwrap_or(0);
    if index == ERROR_HISTORY && sub == 0 {
        // not the highest sub-index but the number of errors recorded; writing 0 clears them
        return Ok(mk("number_of_errors", Unsigned8, Rw, Key::ErrorHistoryCount));
    }
    if sub == 0 {
        if (RPDO_MAP..RPDO_MAP + RPDO_COUNT as u16).contains(&index) {
            return Ok(mk("number_of_mapped_objects", Unsigned8, Rw, Key::MapCount(false, (index - RPDO_MAP) as u8)));
        }
        if (TPDO_MAP..TPDO_MAP + TPDO_COUNT as u16).contains(&index) {
            return Ok(mk("number_of_mapped_objects", Unsigned8, Rw, Key::MapCount(true, (index - TPDO_MAP) as u8)));
        }
    }
    if sub == 0 && obj.kind != ObjectKind::Var {
        return Ok(mk("highest_sub_index", Unsigned8, Const, Key::Count(highest)));
    }
    let idx_in = |base: u16| (index - base) as u8;
    let info = match index {
        DEVICE_TYPE => mk("device_type", Unsigned32, Const, Key::DeviceType),
        ERROR_REGISTER => SubInfo { pdo: true, ..mk("error_register", Unsigned8, Ro, Key::ErrorRegister) },
        ERROR_HISTORY => {
            let name = ERROR_HISTORY_NAMES.get((sub as usize).wrapping_sub(1)).copied().unwrap_or("");
            mk(name, Unsigned32, Ro, Key::ErrorHistory(sub))
        }
        COB_ID_SYNC => mk("cob_id_sync", Unsigned32, Rw, Key::SyncCobId),
        COB_ID_EMCY => SubInfo { node_relative: true, ..mk("cob_id_emcy", Unsigned32, Ro, Key::EmcyCobId) },
        ERROR_BEHAVIOUR => mk("communication_error", Unsigned8, Rw, Key::ErrorBehaviour),
        DEVICE_NAME => mk("manufacturer_device_name", VisibleString, Const, Key::DeviceName),
        SOFTWARE_VERSION => mk("manufacturer_software_version", VisibleString, Const, Key::SoftwareVersion),
        STORE_PARAMETERS => mk("save_all_parameters", Unsigned32, Rw, Key::StoreAll),
        RESTORE_DEFAULTS => mk("restore_all_default_parameters", Unsigned32, Rw, Key::RestoreAll),
        CONSUMER_HEARTBEAT => mk("consumer_heartbeat_time_1", Unsigned32, Rw, Key::ConsumerHeartbeat),
        PRODUCER_HEARTBEAT => mk("producer_heartbeat_time", Unsigned16, Rw, Key::ProducerHeartbeat),
        IDENTITY => {
            let name = IDENTITY_NAMES.get((sub as usize).wrapping_sub(1)).copied().unwrap_or("");
            mk(name, Unsigned32, Ro, Key::Identity(sub))
        }
        SDO_SERVER1 | SDO_SERVER2 => {
            let ch = u8::from(index == SDO_SERVER2);
            let access = if ch == 0 { Ro } else { Rw };
            match sub {
                1 => SubInfo { node_relative: ch == 0, ..mk("cob_id_rx", Unsigned32, access, Key::SdoServer(ch, 1)) },
                2 => SubInfo { node_relative: ch == 0, ..mk("cob_id_tx", Unsigned32, access, Key::SdoServer(ch, 2)) },
                _ => mk("client_node_id", Unsigned8, Rw, Key::SdoServer(ch, 3)),
            }
        }
        i if (RPDO_COMM..RPDO_COMM + RPDO_COUNT as u16).contains(&i) => {
            let n = idx_in(RPDO_COMM);
            match sub {
                1 => SubInfo { node_relative: n == 0, ..mk("cob_id", Unsigned32, Rw, Key::RpdoCobId(n)) },
                _ => mk("transmission_type", Unsigned8, Ro, Key::RpdoType(n)),
            }
        }
        i if (RPDO_MAP..RPDO_MAP + RPDO_COUNT as u16).contains(&i) => {
            let name = MAP_NAMES.get((sub as usize).wrapping_sub(1)).copied().unwrap_or("");
            mk(name, Unsigned32, Rw, Key::RpdoMap(idx_in(RPDO_MAP), sub))
        }
        i if (TPDO_COMM..TPDO_COMM + TPDO_COUNT as u16).contains(&i) => {
            let n = idx_in(TPDO_COMM);
            match sub {
                1 => SubInfo { node_relative: true, ..mk("cob_id", Unsigned32, Rw, Key::TpdoCobId(n)) },
                2 => mk("transmission_type", Unsigned8, Rw, Key::TpdoType(n)),
                3 => mk("inhibit_time", Unsigned16, Rw, Key::TpdoInhibit(n)),
                _ => mk("event_timer", Unsigned16, Rw, Key::TpdoEvent(n)),
            }
        }
        i if (TPDO_MAP..TPDO_MAP + TPDO_COUNT as u16).contains(&i) => {
            let name = MAP_NAMES.get((sub as usize).wrapping_sub(1)).copied().unwrap_or("");
            mk(name, Unsigned32, Rw, Key::TpdoMap(idx_in(TPDO_MAP), sub))
        }
        i if (PARAM_BASE..PARAM_BASE + PARAM_COUNT as u16).contains(&i) => {
            let id = ParamId::from_index((i - PARAM_BASE) as usize).ok_or(Abort::NoObject)?;
            let d = id.desc();
            SubInfo { limits: Some((d.min, d.max)), ..mk(d.name, Real32, Rw, Key::Param(id)) }
        }
        TABLE_SHAPE => {
            let name = SHAPE_NAMES.get((sub as usize).wrapping_sub(1)).copied().unwrap_or("");
            mk(name, Unsigned8, Rw, Key::TableShape(sub))
        }
        TABLE_GRID => mk("gravity_table_grid", Domain, Rw, Key::TableGrid),
        TABLE_TORQUE => mk("gravity_table_torque", Domain, Rw, Key::TableTorque),
        TABLE_SIGMA => mk("gravity_table_sigma", Domain, Rw, Key::TableSigma),
        SERIES_COUNT => mk("gravity_series_count", Unsigned8, Rw, Key::SeriesCount),
        SERIES_TERMS => mk("gravity_series_terms", Domain, Rw, Key::SeriesTerms),
        COMMIT => mk("params_commit", Unsigned8, Wo, Key::Commit),
        COMMIT_ERROR => match sub {
            1 => mk("code", Unsigned8, Ro, Key::ErrorCode),
            2 => mk("param_index", Unsigned16, Ro, Key::ErrorParam),
            _ => mk("message", VisibleString, Ro, Key::ErrorMessage),
        },
        CLEAR_FAULTS => mk("clear_faults", Unsigned8, Wo, Key::ClearFaults),
        PENDING => mk("params_pending", Unsigned8, Ro, Key::Pending),
        PARAMS_CRC => match sub {
            1 => mk("active_crc", Unsigned32, Ro, Key::ActiveCrc),
            _ => mk("staged_crc", Unsigned32, Ro, Key::StagedCrc),
        },
        COMMIT_CRC => mk("params_commit_crc", Unsigned32, Wo, Key::CommitCrc),
        JOINT_STATE => {
            let name = JOINT_STATE_NAMES.get((sub as usize).wrapping_sub(1)).copied().unwrap_or("");
            let dtype = if sub == JS_FAULTS || sub == JS_GAIN { Unsigned16 } else { Integer16 };
            SubInfo { pdo: true, ..mk(name, dtype, Ro, Key::JointState(sub)) }
        }
        JOINT_STATE_F32 => {
            let name = JOINT_STATE_F32_NAMES.get((sub as usize).wrapping_sub(1)).copied().unwrap_or("");
            let dtype = if sub == JF_MODE { Unsigned8 } else { Real32 };
            SubInfo { pdo: true, ..mk(name, dtype, Ro, Key::JointStateF32(sub)) }
        }
        HOST_COMMAND => SubInfo { pdo: true, ..mk("assist_cmd", Integer16, Rw, Key::AssistCmd) },
        OTHER_ANGLES => {
            let name = OTHER_NAMES.get((sub as usize).wrapping_sub(1)).copied().unwrap_or("");
            SubInfo { pdo: true, ..mk(name, Integer16, Rw, Key::OtherAngle(sub)) }
        }
        _ => return Err(Abort::NoObject),
    };
    Ok(info)
}
