//! The sensor-point reader (`sensors::parse`, rtrace -I format) and the
//! placement of its points in the Cornell box (`sensors::receivers`): any
//! bytes give unit-normal points on surfaces facing their way, or an error
//! naming the file; never a panic or a hang.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| radiosity_fuzz::check_sensors(data));
