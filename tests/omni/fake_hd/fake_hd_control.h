/* SPDX-License-Identifier: Apache-2.0 */
/* Test control of the fake libHD (fake_hd.cpp). The fake exports the HD C functions the
 * backend uses, with the behaviour the OpenHaptics reference documents (docs/OMNI.md §2),
 * driven by a simulated Omni; these extra functions let a test steer it. The
 * tests resolve them with dlsym on the same handle the backend loaded, so the backend reaches
 * the fake only through its ordinary dlopen path.
 *
 * Everything passing through the fake proves our binding against the DOCUMENTED behaviour of
 * the HD API, as we read it, not against the real driver. */
#ifndef TOONFORCE_FAKE_HD_CONTROL_H
#define TOONFORCE_FAKE_HD_CONTROL_H

#ifdef __cplusplus
extern "C" {
#endif

/* Where an injected error is raised. */
#define TF_FAKE_HD_AT_BEGIN 0              /* inside hdBeginFrame */
#define TF_FAKE_HD_AT_END 1                /* inside hdEndFrame */
#define TF_FAKE_HD_AT_INIT 2               /* hdInitDevice fails with it */
#define TF_FAKE_HD_AT_START 3              /* hdStartScheduler fails with it */
#define TF_FAKE_HD_AT_CALIBRATION_UPDATE 4 /* hdUpdateCalibration fails with it */

/* A call that broke a documented rule (counted in protocol_violations) without an HD error:
 * a frame or state call from another thread than the running scheduler's; hdInitDevice while
 * the scheduler runs (devices are initialised before it starts). */
#define TF_FAKE_HD_WRONG_THREAD 0xFFFFu
#define TF_FAKE_HD_INIT_WHILE_RUNNING 0xFFFEu

typedef struct TfFakeHdStats {
  unsigned long ticks;                       /* scheduler ticks run */
  double sim_time_s;                         /* simulated time, skipped periods included */
  unsigned long frames;                      /* completed hdBeginFrame/hdEndFrame pairs */
  double last_force_n[3];                    /* last HD_CURRENT_FORCE commanded [N, device frame], as given */
  double max_force_norm_n;                   /* largest commanded force norm since reset [N], as given */
  double applied_force_n[3];                 /* what the simulated motors applied last frame [N] */
  int force_output_enabled;                  /* HD_FORCE_OUTPUT */
  unsigned long enabled_uncalibrated_frames; /* frames ended with output on while not calibrated */
  unsigned long nonzero_uncalibrated_frames; /* frames commanding a non-zero force while not calibrated */
  unsigned long protocol_violations;         /* calls breaking a documented rule (never injected) */
  unsigned int last_violation;               /* HD code it raised, or TF_FAKE_HD_WRONG_THREAD */
  char last_violation_call[64];              /* the function and parameter */
  unsigned long errors_raised;               /* errors pushed (injected, natural and violations) */
  int async_callbacks;                       /* scheduled and still active */
  int scheduler_running;
  int device_initialized;
  unsigned long init_calls;
  unsigned long calibration_checks;
  unsigned long calibration_updates;
  unsigned long calibration_update_errors;    /* updates the device refused with an error */
  unsigned long calibration_updates_in_frame; /* updates between hdBeginFrame and hdEndFrame */
  unsigned long disable_device_calls;         /* hdDisableDevice calls since reset */
  unsigned int calibration;                   /* HD_CALIBRATION_OK / NEEDS_UPDATE / NEEDS_MANUAL_INPUT */
  double position_mm[3];                      /* true HIP position [mm, device frame] */
  double reported_position_mm[3];             /* what HD_CURRENT_POSITION said at the last hdBeginFrame */
  double joint_angles_rad[3];                 /* encoder-quantised base joints at the last hdBeginFrame */
  double motor_temperature;                   /* the thermal model, 0 cold .. 1 warm */
  double scheduler_rate_hz;
  unsigned int handle; /* the device's HHD (index + 1) */
  int device_count;    /* devices configured */
  char name[64];       /* the device's configured name */
  char serial[32];     /* what HD_DEVICE_SERIAL_NUMBER answers for it */
} TfFakeHdStats;

/* Back to the defaults (scheduler must be stopped): one device, "Default Device" (serial
 * "FAKE-0001"), which hdInitDevice opens whatever name it is given; calibrated (inkwell
 * style), version "3.4.0", 3.3 N nominal maximum, hand pinned at the device origin,
 * free-running scheduler. */
void tf_fake_hd_reset(void);

/* Several devices, as Touch_Setup configures them by name. The first call after a reset names
 * the one device, each further call adds one (at most 4); from the first call on, hdInitDevice
 * opens the device of that exact name (HD_DEFAULT_DEVICE, null: the first) and answers an
 * unknown name with HD_COMM_CONFIG_ERROR (the reference does not say which code; the name is
 * missing from the configuration). Call before any hdInitDevice. Returns the device's index
 * (its handle is index + 1), or -1 when the name is empty or taken, too many, or too late.
 * Every device has its own arm, calibration, limits, force, frame and counts, all at their
 * defaults; the one scheduler runs every scheduled callback each tick. */
int tf_fake_hd_add_device(const char* name, const char* serial);
/* Which device the other tf_fake_hd_* calls below (settings, the hand, injected errors,
 * tf_fake_hd_get_stats) act on, by name (null: the first); the default after a reset is the
 * first. Scheduler-wide settings and counts (manual mode, steps, overruns, version, rate,
 * ticks, protocol violations, errors raised) are the library's, whichever is selected.
 * Returns the device's index, or -1 (selection unchanged) for an unknown name. */
int tf_fake_hd_select_device(const char* name);
/* 1: the scheduler runs a tick only when tf_fake_hd_step asks (deterministic tests);
 * 0: it runs in real time at the scheduler rate. Set before hdStartScheduler. */
void tf_fake_hd_set_manual(int on);
/* Manual mode: runs `ticks` scheduler ticks in the scheduler thread and waits for them.
 * Returns the ticks run (0 when the scheduler is not running). */
unsigned long tf_fake_hd_step(unsigned long ticks);

void tf_fake_hd_set_version(const char* version); /* what hdGetString(HD_VERSION) answers */
void tf_fake_hd_set_limits(double max_force_n, double max_continuous_force_n, double stiffness_n_per_mm,
                           double damping_n_s_per_mm);
/* The calibration state and the styles the device supports. The state then changes as a
 * person's actions change it (what OpenHaptics' calibration example and the ROS node expect):
 *   NEEDS_MANUAL_INPUT -> NEEDS_UPDATE when the stylus is docked in the inkwell (inkwell style)
 *                         or the arm has swept its workspace (auto style: each base joint
 *                         through 0.5 rad);
 *   NEEDS_UPDATE -> OK on hdUpdateCalibration with a supported style;
 *   NEEDS_MANUAL_INPUT -> OK on hdUpdateCalibration(ENCODER_RESET) (the arm is taken to be in
 *                         its reset pose).
 * hdUpdateCalibration while manual input is still needed raises an error (see
 * tf_fake_hd_set_calibration_update_error) and changes nothing. */
void tf_fake_hd_set_calibration(unsigned int state, int styles);
/* The HD error hdUpdateCalibration raises when manual input is needed (default
 * HD_INVALID_OPERATION; the code the real driver raises is not documented). */
void tf_fake_hd_set_calibration_update_error(unsigned int code);
void tf_fake_hd_set_inkwell(int stylus_in_inkwell);
/* What hdGetString(HD_DEVICE_MODEL_TYPE) answers (default "Touch (toonforce fake libHD)"). */
void tf_fake_hd_set_model(const char* model);
void tf_fake_hd_set_buttons(int buttons);
/* Raises `code` (with `internal`) at `where` on each of the next `count` occasions, on the selected
 * device (at scheduler start: whichever device). */
void tf_fake_hd_inject_error(unsigned int code, int internal, int where, unsigned long count);
/* The next tick spans `periods` scheduler periods (the ones between were skipped). */
void tf_fake_hd_inject_overrun(unsigned int periods);
/* What hdGetSchedulerTimeStamp answers at the end of a callback in manual mode [s]. */
void tf_fake_hd_set_callback_time(double seconds);
/* The hand holds the HIP exactly at `position_mm` (device frame), whatever the force. */
void tf_fake_hd_pin_hand(const double position_mm[3]);
/* The hand is a spring-damper toward `target_mm` (device frame) on the simulated mass. */
void tf_fake_hd_spring_hand(const double target_mm[3], double stiffness_n_per_m, double damping_n_s_per_m);
/* Overrides the motor thermal model (t >= 0) or returns to it (t < 0). */
void tf_fake_hd_set_motor_temperature(double t);
/* 0: HD_MOTOR_TEMPERATURE answers HD_INVALID_ENUM, as on a device without the model. */
void tf_fake_hd_set_temperature_supported(int supported);
void tf_fake_hd_get_stats(TfFakeHdStats* stats);

#ifdef __cplusplus
}
#endif
#endif /* TOONFORCE_FAKE_HD_CONTROL_H */
