/* libjointspace_klipper.so: jointspace's kinematics for Klipper and Kalico (C interface).
 * jointspace.py hands these declarations to cffi (lines starting with '#' are left out), so keep them to
 * plain declarations. struct stepper_kinematics is Klipper's (klippy/chelper/itersolve.h).
 * Functions returning int give 0 on success and a negative number on failure, with the reason in `error`.
 * No function unwinds into the caller (an internal error becomes the function's failure value), none returns NaN,
 * and moves or points with a non-finite coordinate, or one beyond 1e9 mm, are refused with the value named. */
#ifndef JOINTSPACE_H
#define JOINTSPACE_H
/* The library version this header belongs to (the library refuses to build from a header naming another; the
 * plug-in refuses a library reporting another, as jointspace_version's "jointspace-klipper X.Y.Z"). */
#define JOINTSPACE_VERSION "0.1.0"
#include <stddef.h>
struct stepper_kinematics;
struct jointspace_machine;

const char *jointspace_version(void);
/* The commit the library was built from: 12 hex digits, or "unknown" (built without git). */
const char *jointspace_commit(void);
/* FNV-1a hash of this file's bytes as the library was built from it: jointspace.py refuses another. */
unsigned long long jointspace_header_hash(void);
/* Klipper's struct stepper_kinematics or struct move ("stepper_kinematics", "move") as the library was built for
 * it: "size N" (the struct it allocates), then "field offset size" lines; NULL for another name. */
const char *jointspace_struct_layout(const char *name);

struct jointspace_machine *jointspace_machine_new(const char *config_text, int fused_arithmetic,
                                                  char *error, size_t error_len);
struct jointspace_machine *jointspace_machine_new_from_file(const char *path, int fused_arithmetic,
                                                            char *error, size_t error_len);
void jointspace_machine_free(struct jointspace_machine *m);
const char *jointspace_machine_read_keys(struct jointspace_machine *m);
/* The value the machine was built with for a [printer] key (offset_x, link1_length, arm_zero_offset, max_z_velocity,
 * max_z_accel...): 0, or -1 when it has no such key. The plug-in asks instead of reading the key a second time. */
int jointspace_machine_value(struct jointspace_machine *m, const char *key, double *value);
int jointspace_motor_count(struct jointspace_machine *m);
const char *jointspace_motor_name(struct jointspace_machine *m, int index);

struct stepper_kinematics *jointspace_stepper_alloc(struct jointspace_machine *m, const char *name);
struct stepper_kinematics *jointspace_linear_stepper_alloc(double cx, double cy, double cz,
                                                           int fused_arithmetic);
/* Probe of the host's arithmetic: `move` is Klipper's struct move. */
double jointspace_polar_radius(const void *move, double move_time, int fused_arithmetic);

int jointspace_forward(struct jointspace_machine *m, const double *motors, double *xyz,
                       char *error, size_t error_len);
int jointspace_inverse(struct jointspace_machine *m, const double *xyz, const double *previous,
                       double *motors, char *error, size_t error_len);
int jointspace_check_move(struct jointspace_machine *m, double start_x, double start_y, double start_z,
                          double end_x, double end_y, double end_z, double speed, double accel,
                          double *limits, char *error, size_t error_len);
int jointspace_caps_corners(struct jointspace_machine *m);
double jointspace_junction_speed(struct jointspace_machine *m, const double *points, double prev_accel,
                                 double next_accel);
int jointspace_rotation_centre(struct jointspace_machine *m, double *out);
int jointspace_move_waypoints(struct jointspace_machine *m, double start_x, double start_y, double start_z,
                              double end_x, double end_y, double end_z, double speed, double accel,
                              double bed_angle, int cut_spans, double *out, int max, char *error,
                              size_t error_len);
int jointspace_scara_pattern(struct jointspace_machine *m, int count, double cross_size, char *gcode,
                             size_t gcode_len, char *template_text, size_t template_len);
/* The Hall-sensor centre scan ([jointspace] hall_* settings). */
struct jointspace_hall_scan {
    int magnet_count;
    double ring_radius, max_offset, pass_pitch, field_reach, threshold;
    double adc_reference, sensitivity, saturation, max_sigma, sensor_alignment;
};
int jointspace_scan_passes(const struct jointspace_hall_scan *settings, double *arms, int max,
                           double *bed_overlap, char *error, size_t error_len);
int jointspace_scan_centre(const struct jointspace_hall_scan *settings, const double *samples, size_t count,
                           double *result, char *csv, size_t csv_len, char *report, size_t report_len);
int jointspace_declared_home(struct jointspace_machine *m, double *xyz);
int jointspace_reach_margin(struct jointspace_machine *m, double x, double y, double z, double *margin);
#endif
