//! The ROS 2 messages isoline reads from and writes to bags, as serde structs for their
//! CDR encoding (`cdr-encoding`), with the `ros2msg` schema texts a bag's channels
//! carry. Only what a 2D scanner stream needs: the ROS 2 interface crates pull in a
//! whole DDS stack for these few structs.

use byteorder::{BigEndian, LittleEndian};
use serde::{Deserialize, Serialize};

/// `builtin_interfaces/msg/Time`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Time {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}

impl Time {
    /// Seconds as one number; `None` for the zero time (no stamp).
    pub fn seconds(self) -> Option<f64> {
        (self.sec != 0 || self.nanosec != 0)
            .then(|| f64::from(self.sec) + f64::from(self.nanosec) * 1e-9)
    }

    /// The time `t` (seconds, at least 0): whole seconds saturate at `i32::MAX`.
    pub fn from_seconds(t: f64) -> Time {
        let t = if t.is_finite() { t.max(0.0) } else { 0.0 };
        let sec = t.floor().min(f64::from(i32::MAX));
        let nanosec = (((t - sec) * 1e9).round() as u32).min(999_999_999);
        Time {
            sec: sec as i32,
            nanosec,
        }
    }
}

/// `std_msgs/msg/Header`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// When the data were taken.
    pub stamp: Time,
    /// The coordinate frame of the data.
    pub frame_id: String,
}

/// `sensor_msgs/msg/LaserScan`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LaserScan {
    /// Stamp of the first beam and the scanner's frame.
    pub header: Header,
    /// Bearing of the first beam, radians.
    pub angle_min: f32,
    /// Bearing of the last beam, radians.
    pub angle_max: f32,
    /// Angle between beams, radians.
    pub angle_increment: f32,
    /// Time between beams, seconds.
    pub time_increment: f32,
    /// Time between scans, seconds.
    pub scan_time: f32,
    /// Nearer ranges are no returns.
    pub range_min: f32,
    /// Farther ranges are no returns.
    pub range_max: f32,
    /// Ranges, metres (NaN or inf: no return).
    pub ranges: Vec<f32>,
    /// Intensities (may be empty).
    pub intensities: Vec<f32>,
}

/// `geometry_msgs/msg/Vector3` and `geometry_msgs/msg/Point` (the same fields).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Quaternion::of_yaw(0.0)
    }
}

impl Quaternion {
    /// The rotation by `yaw` about the z axis.
    pub fn of_yaw(yaw: f64) -> Quaternion {
        let (s, c) = (0.5 * yaw).sin_cos();
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: s,
            w: c,
        }
    }

    /// The heading of the rotated x axis in the xy plane.
    pub fn yaw(self) -> f64 {
        let Quaternion { x, y, z, w } = self;
        (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z))
    }
}

/// `geometry_msgs/msg/Pose`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position.
    pub position: Vector3,
    /// Orientation.
    pub orientation: Quaternion,
}

/// `geometry_msgs/msg/PoseWithCovariance` (the 6x6 covariance as rows: serde's arrays
/// stop at 32 elements, and CDR lays both out alike).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// Its covariance, row-major.
    pub covariance: [[f64; 6]; 6],
}

/// `geometry_msgs/msg/Twist`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    /// Linear velocity.
    pub linear: Vector3,
    /// Angular velocity.
    pub angular: Vector3,
}

/// `geometry_msgs/msg/TwistWithCovariance`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    /// The twist.
    pub twist: Twist,
    /// Its covariance, row-major.
    pub covariance: [[f64; 6]; 6],
}

/// `nav_msgs/msg/Odometry`: the pose of `child_frame_id` in `header.frame_id`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    /// Stamp and parent frame.
    pub header: Header,
    /// The frame whose pose this is.
    pub child_frame_id: String,
    /// The pose.
    pub pose: PoseWithCovariance,
    /// The velocity.
    pub twist: TwistWithCovariance,
}

/// `geometry_msgs/msg/Transform`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    /// Translation.
    pub translation: Vector3,
    /// Rotation.
    pub rotation: Quaternion,
}

/// `geometry_msgs/msg/TransformStamped`: the pose of `child_frame_id` in
/// `header.frame_id`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    /// Stamp and parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// The transform.
    pub transform: Transform,
}

/// `tf2_msgs/msg/TFMessage`, the messages of `/tf` and `/tf_static`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TfMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

/// Schema names.
pub const LASER_SCAN: &str = "sensor_msgs/msg/LaserScan";
/// Schema names.
pub const ODOMETRY: &str = "nav_msgs/msg/Odometry";
/// Schema names.
pub const TF_MESSAGE: &str = "tf2_msgs/msg/TFMessage";

const HEADER_MSG: &str = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
    ================================================================================\n\
    MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";

const SEPARATOR: &str =
    "================================================================================\n";

/// The `ros2msg` schema text of `name` (one of the schema names above).
pub fn schema_text(name: &str) -> Option<String> {
    let vector = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n";
    let quaternion =
        "MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n";
    Some(match name {
        LASER_SCAN => format!(
            "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\n\
             float32 angle_increment\nfloat32 time_increment\nfloat32 scan_time\n\
             float32 range_min\nfloat32 range_max\nfloat32[] ranges\nfloat32[] intensities\n\
             {SEPARATOR}{HEADER_MSG}"
        ),
        ODOMETRY => format!(
            "std_msgs/Header header\nstring child_frame_id\n\
             geometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n\
             {SEPARATOR}{HEADER_MSG}{SEPARATOR}\
             MSG: geometry_msgs/PoseWithCovariance\nPose pose\nfloat64[36] covariance\n\
             {SEPARATOR}MSG: geometry_msgs/Pose\nPoint position\nQuaternion orientation\n\
             {SEPARATOR}MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n\
             {SEPARATOR}{quaternion}{SEPARATOR}\
             MSG: geometry_msgs/TwistWithCovariance\nTwist twist\nfloat64[36] covariance\n\
             {SEPARATOR}MSG: geometry_msgs/Twist\nVector3 linear\nVector3 angular\n\
             {SEPARATOR}{vector}"
        ),
        TF_MESSAGE => format!(
            "geometry_msgs/TransformStamped[] transforms\n{SEPARATOR}\
             MSG: geometry_msgs/TransformStamped\nstd_msgs/Header header\n\
             string child_frame_id\nTransform transform\n{SEPARATOR}{HEADER_MSG}{SEPARATOR}\
             MSG: geometry_msgs/Transform\nVector3 translation\nQuaternion rotation\n\
             {SEPARATOR}{vector}{SEPARATOR}{quaternion}"
        ),
        _ => return None,
    })
}

/// Decodes a CDR message with its 4-byte encapsulation header (plain CDR, either byte
/// order); the error says what is wrong.
pub fn decode<T: serde::de::DeserializeOwned>(data: &[u8]) -> Result<T, String> {
    let (head, body) = data
        .split_at_checked(4)
        .ok_or_else(|| format!("{} bytes, shorter than a CDR header", data.len()))?;
    let decoded = match head[..2] {
        [0, 0] => cdr_encoding::from_bytes::<T, BigEndian>(body),
        [0, 1] => cdr_encoding::from_bytes::<T, LittleEndian>(body),
        _ => {
            return Err(format!(
                "encapsulation {:02x}{:02x} is not plain CDR",
                head[0], head[1]
            ))
        }
    };
    decoded.map(|(v, _)| v).map_err(|e| format!("CDR: {e}"))
}

/// Encodes a message as little-endian CDR with its encapsulation header.
pub fn encode<T: Serialize>(msg: &T) -> Vec<u8> {
    let mut out = vec![0, 1, 0, 0];
    // Serializing plain structs into a Vec cannot fail.
    out.extend(cdr_encoding::to_vec::<T, LittleEndian>(msg).expect("CDR of a plain struct"));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_round_trip_and_bad_bytes_are_errors() {
        let scan = LaserScan {
            header: Header {
                stamp: Time::from_seconds(12.25),
                frame_id: "laser".into(),
            },
            angle_min: -1.0,
            angle_max: 1.0,
            angle_increment: 0.5,
            range_max: 10.0,
            ranges: vec![1.0, f32::INFINITY, 2.0, 3.0, 4.0],
            ..Default::default()
        };
        let bytes = encode(&scan);
        assert_eq!(decode::<LaserScan>(&bytes).unwrap(), scan);
        assert_eq!(scan.header.stamp.seconds(), Some(12.25));
        let odom = Odometry {
            child_frame_id: "base_link".into(),
            pose: PoseWithCovariance {
                pose: Pose {
                    orientation: Quaternion::of_yaw(0.7),
                    ..Default::default()
                },
                ..Default::default()
            },
            ..Default::default()
        };
        let back: Odometry = decode(&encode(&odom)).unwrap();
        assert!((back.pose.pose.orientation.yaw() - 0.7).abs() < 1e-12);
        // Cut short, a wrong header, a string longer than the message.
        assert!(decode::<LaserScan>(&bytes[..bytes.len() - 3]).is_err());
        assert!(decode::<LaserScan>(&[0, 1]).is_err());
        let mut bad = bytes.clone();
        bad[1] = 7;
        assert!(decode::<LaserScan>(&bad)
            .unwrap_err()
            .contains("encapsulation"));
        let mut huge = bytes;
        huge[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode::<LaserScan>(&huge).is_err());
        for name in [LASER_SCAN, ODOMETRY, TF_MESSAGE] {
            assert!(schema_text(name).is_some());
        }
    }
}
