/* syndds_cyclone_controller: an external controller for one syndds vehicle, written in C on
 * CycloneDDS from docs/protocol.md ("External controllers") alone. It joins a run as the
 * member external/<vehicle>, follows the time protocol frame by frame (grant -> wait for the
 * announced vehicle state -> command -> done), and drives the vehicle along a path given on
 * the command line with pure pursuit and a proportional speed controller.
 *
 * Exit status (as every syndds program): 0 run completed, 1 bad command line or DDS
 * configuration, 2 run aborted, 3 this process failed (coordinator lost, no coordinator,
 * inputs missing, protocol error), 4 refused (another participant is this member),
 * 130 interrupted.
 */
#define _POSIX_C_SOURCE 200809L

#include <dds/dds.h>
#include <errno.h>
#include <inttypes.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "pursuit.h"
#include "syndds.h"

enum {
  EXIT_COMPLETED = 0,
  EXIT_BAD_CONFIG = 1,
  EXIT_ABORTED = 2,
  EXIT_FAILED = 3,
  EXIT_REFUSED = 4,
  EXIT_INTERRUPTED = 130
};

enum { PROTOCOL_VERSION = 6, WRITER_DEPTH = 8, READER_DEPTH = 64 };

/* Participant liveliness: the coordinator notices this process's death after the lease. */
#define LEASE_DURATION "2s"
#define SPDP_INTERVAL "500ms"

#define NAME_SIZE 256
#define MAX_PENDING_GRANTS 64
#define MAX_NEEDED 8
#define MAX_STATES 64
#define MAX_LOST 64
#define TAKE_BATCH 16

/* The only state shared with the signal handler. */
static volatile sig_atomic_t interrupted_flag = 0;

static void on_signal(int sig) {
  (void)sig;
  interrupted_flag = 1;
}

/* ---- command line ------------------------------------------------------------------------ */

typedef struct options {
  int domain;
  const char* run_id;
  const char* vehicle;
  bool has_fingerprint;
  uint64_t fingerprint;
  const char* interface_name;
  double join_timeout_s;
  double input_timeout_s;
  const char* checkpoint_dir;
  bool rejoin;
  bool quiet;
  pursuit_path path;
  pursuit_config control;
} options;

static void usage(FILE* out) {
  fprintf(out,
          "Usage: syndds_cyclone_controller --domain D --run-id R --vehicle ID\n"
          "           --waypoints \"x,y;x,y;...\" [options]\n"
          "Joins syndds run R on DDS domain D as the member external/ID and drives vehicle ID\n"
          "along the waypoints (scenario ENU metres) with pure pursuit.\n"
          "\n"
          "  --domain D            DDS domain of the run (as given to run_scenario.sh / plan)\n"
          "  --run-id R            run id (the DDS partition of the run)\n"
          "  --vehicle ID          vehicle with `controller: {type: external}`\n"
          "  --waypoints LIST      path: \"x,y;x,y;...\", at least two points\n"
          "  --speed MPS           cruise speed (default 5)\n"
          "  --fingerprint F       scenario fingerprint to insist on (default: echo the\n"
          "                        coordinator's)\n"
          "  --lookahead M         lookahead at standstill (default 3)\n"
          "  --lookahead-gain S    extra lookahead per m/s of speed (default 0.6)\n"
          "  --wheelbase M         axle to axle (default 3.378, HMMWV)\n"
          "  --max-steer-deg DEG   road-wheel angle at full steering (default 30.23)\n"
          "  --speed-gain G        throttle/brake per m/s of speed error (default 0.5)\n"
          "  --interface NAME      network interface for CycloneDDS (e.g. lo); default: its own\n"
          "                        choice. CYCLONEDDS_URI, if set, is applied on top.\n"
          "  --join-timeout S      give up without a coordinator after S s (default 35)\n"
          "  --checkpoint-dir DIR  where to keep this controller's checkpoints when the run\n"
          "                        takes them (scenario checkpoint: every_s); without it the\n"
          "                        run's checkpoints are incomplete and it cannot recover\n"
          "  --rejoin              restarted after this controller was lost (on_member_loss:\n"
          "                        recover): take part from the rollback that names it\n"
          "  --input-timeout S     give up when a granted frame's vehicle state is missing\n"
          "                        after S s (default: 3/4 of the coordinator's frame deadline)\n"
          "  --quiet               log only errors\n"
          "  -h, --help            this text\n"
          "\n"
          "Exit status: 0 completed, 1 bad command line, 2 run aborted, 3 this process\n"
          "failed, 4 refused (another participant is this member), 130 interrupted.\n");
}

static int bad_option(const char* option, const char* fmt, ...) {
  va_list args;
  va_start(args, fmt);
  fprintf(stderr, "syndds_cyclone_controller: %s: ", option);
  vfprintf(stderr, fmt, args);
  fprintf(stderr, " (see --help)\n");
  va_end(args);
  return 0;
}

static int parse_double(const char* option, const char* text, double lo, double hi,
                        double* out) {
  char* end = NULL;
  errno = 0;
  const double v = strtod(text, &end);
  if (end == text || *end != '\0' || errno == ERANGE || !isfinite(v)) {
    return bad_option(option, "expected a number, got \"%s\"", text);
  }
  if (v < lo || v > hi) {
    return bad_option(option, "must be between %g and %g, got %s", lo, hi, text);
  }
  *out = v;
  return 1;
}

static bool valid_name(const char* s, const char* extra) {
  if (*s == '\0') return false;
  for (const char* c = s; *c; ++c) {
    const bool ok = (*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') ||
                    (*c >= '0' && *c <= '9') || strchr(extra, *c) != NULL;
    if (!ok) return false;
  }
  return true;
}

/* Returns 1 on success, 0 after printing an error naming the option, -1 for --help. */
static int parse_options(int argc, char** argv, options* o) {
  memset(o, 0, sizeof *o);
  o->domain = -1;
  o->join_timeout_s = 35.0;
  o->input_timeout_s = 0.0; /* 0: 3/4 of the coordinator's frame_timeout_s */
  o->control = pursuit_default_config();
  bool have_path = false;
  double max_steer_deg = 30.23;
  for (int i = 1; i < argc; ++i) {
    const char* opt = argv[i];
    if (strcmp(opt, "-h") == 0 || strcmp(opt, "--help") == 0) return -1;
    if (strcmp(opt, "--quiet") == 0) {
      o->quiet = true;
      continue;
    }
    if (strcmp(opt, "--rejoin") == 0) {
      o->rejoin = true;
      continue;
    }
    if (strncmp(opt, "--", 2) != 0) return bad_option(opt, "unexpected argument");
    if (i + 1 >= argc) return bad_option(opt, "needs a value");
    const char* value = argv[++i];
    double v = 0.0;
    if (strcmp(opt, "--domain") == 0) {
      if (!parse_double(opt, value, 0, 232, &v)) return 0;
      if (v != floor(v)) return bad_option(opt, "must be a whole number, got %s", value);
      o->domain = (int)v;
    } else if (strcmp(opt, "--run-id") == 0) {
      if (!valid_name(value, "_-.:")) {
        return bad_option(opt, "\"%s\" is not a run id (letters, digits, _ - . : only)", value);
      }
      o->run_id = value;
    } else if (strcmp(opt, "--vehicle") == 0) {
      if (!valid_name(value, "_-.")) {
        return bad_option(opt, "\"%s\" is not a vehicle id (letters, digits, _ - . only)",
                          value);
      }
      o->vehicle = value;
    } else if (strcmp(opt, "--fingerprint") == 0) {
      char* end = NULL;
      errno = 0;
      const unsigned long long f = strtoull(value, &end, 10);
      if (end == value || *end != '\0' || errno == ERANGE || value[0] == '-') {
        return bad_option(opt, "expected an unsigned 64-bit number, got \"%s\"", value);
      }
      o->has_fingerprint = true;
      o->fingerprint = (uint64_t)f;
    } else if (strcmp(opt, "--waypoints") == 0) {
      char error[256];
      if (!pursuit_parse_waypoints(value, &o->path, error, sizeof error)) {
        return bad_option(opt, "%s", error);
      }
      have_path = true;
    } else if (strcmp(opt, "--speed") == 0) {
      if (!parse_double(opt, value, 0.1, 30.0, &o->control.speed_mps)) return 0;
    } else if (strcmp(opt, "--lookahead") == 0) {
      if (!parse_double(opt, value, 0.5, 100.0, &o->control.lookahead_min_m)) return 0;
    } else if (strcmp(opt, "--lookahead-gain") == 0) {
      if (!parse_double(opt, value, 0.0, 10.0, &o->control.lookahead_gain_s)) return 0;
    } else if (strcmp(opt, "--wheelbase") == 0) {
      if (!parse_double(opt, value, 0.1, 20.0, &o->control.wheelbase_m)) return 0;
    } else if (strcmp(opt, "--max-steer-deg") == 0) {
      if (!parse_double(opt, value, 1.0, 89.0, &max_steer_deg)) return 0;
    } else if (strcmp(opt, "--speed-gain") == 0) {
      if (!parse_double(opt, value, 0.0, 100.0, &o->control.speed_gain)) return 0;
    } else if (strcmp(opt, "--interface") == 0) {
      if (!valid_name(value, "_-.:")) {
        return bad_option(opt, "\"%s\" is not an interface name", value);
      }
      o->interface_name = value;
    } else if (strcmp(opt, "--checkpoint-dir") == 0) {
      if (*value == '\0' || strlen(value) > 1024) {
        return bad_option(opt, "expected a folder, got \"%s\"", value);
      }
      o->checkpoint_dir = value;
    } else if (strcmp(opt, "--join-timeout") == 0) {
      if (!parse_double(opt, value, 0.1, 3600.0, &o->join_timeout_s)) return 0;
    } else if (strcmp(opt, "--input-timeout") == 0) {
      if (!parse_double(opt, value, 0.1, 3600.0, &o->input_timeout_s)) return 0;
    } else {
      return bad_option(opt, "unknown option");
    }
  }
  o->control.max_steer_rad = max_steer_deg * 3.14159265358979323846 / 180.0;
  if (o->domain < 0) return bad_option("--domain", "is required");
  if (!o->run_id) return bad_option("--run-id", "is required");
  if (!o->vehicle) return bad_option("--vehicle", "is required");
  if (!have_path) return bad_option("--waypoints", "is required");
  return 1;
}

/* ---- helpers ----------------------------------------------------------------------------- */

static double now_s(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static bool copy_name(char* dst, const char* src) {
  const size_t n = strlen(src ? src : "");
  if (n >= NAME_SIZE) return false;
  memcpy(dst, src ? src : "", n + 1);
  return true;
}

/* A GUID prefix the way Fast DDS prints one (and syndds announces it): twelve lowercase hex
 * bytes joined by dots. */
static void format_guid_prefix(const uint8_t* v, char* out, size_t size) {
  size_t at = 0;
  for (int i = 0; i < 12 && at + 3 < size; ++i) {
    at += (size_t)snprintf(out + at, size - at, i == 0 ? "%02x" : ".%02x", v[i]);
  }
}

/* ---- run state --------------------------------------------------------------------------- */

typedef struct needed_input {
  char writer[NAME_SIZE];
  uint32_t count;
} needed_input;

typedef struct pending_grant {
  int64_t frame;
  double sim_time_s;
  uint32_t epoch;
  bool rollback;    /* restore the checkpoint of `frame`, report it done (recover) */
  bool rejoined_us; /* the rollback names this participant as a restarted member */
  size_t needed_count;
  needed_input needed[MAX_NEEDED]; /* vehicle_state samples of our vehicle stamped frame-1 */
} pending_grant;

typedef struct stored_state {
  bool used;
  int64_t frame;
  char source[NAME_SIZE];
  double x, y, yaw, forward_speed;
} stored_state;

typedef struct controller {
  options opt;
  char member_id[NAME_SIZE];
  char own_guid[64];

  /* DDS entities */
  dds_entity_t participant;
  dds_entity_t waitset;
  dds_entity_t announce_reader, grant_reader, control_reader, state_reader, participant_reader;
  dds_entity_t announce_writer, done_writer, command_writer;

  /* the coordinator */
  bool coordinator_known;
  bool coordinator_lost;
  char coordinator_guid[64];
  char coordinator_host[NAME_SIZE];
  int32_t coordinator_pid;
  int32_t coordinator_protocol;
  uint64_t coordinator_fingerprint;
  double coordinator_frame_timeout_s;
  int64_t coordinator_checkpoint_every; /* frames between the run's checkpoints (0: none) */
  bool expects_us;
  /* Admission: the coordinator names this participant as the member (admitted) or not. */
  bool admitted;
  bool refused;
  char refusal[1024];
  /* The coordinator's process when it runs on this machine ("" otherwise): watched directly,
   * so that its exit is seen within a poll interval instead of a DDS lease. */
  int coordinator_watch_pid;
  unsigned long long coordinator_watch_start;
  char lost_guids[MAX_LOST][64]; /* participants gone before the coordinator was known */
  size_t lost_count;

  /* the protocol */
  bool joined;
  int64_t next_frame;
  pending_grant grants[MAX_PENDING_GRANTS];
  size_t grant_head, grant_count;
  int64_t waiting_frame;
  double waiting_since;
  stored_state states[MAX_STATES];
  bool control_received;
  int32_t control_status;
  int64_t control_final_frame;
  char control_reason[1024];
  char failure[1024];

  /* checkpoints and recovery (docs/protocol.md, "External controllers") */
  uint32_t epoch;             /* of the grants this controller answers */
  int64_t restored_from;      /* the checkpoint it rolled back to (-1: none) */
  bool rejoined;              /* --rejoin: the rollback naming it has come */
  bool has_resumed_input;     /* the next frame's input comes from the checkpoint */
  bool resumed_has_state;
  stored_state resumed_input;
  bool warned_no_checkpoint_dir;

  /* the path follower */
  pursuit_state pursuit;
  int64_t frames_done;
  int64_t commands_sent;
  double last_x, last_y;
} controller;

static void log_info(const controller* c, const char* fmt, ...) {
  if (c->opt.quiet) return;
  va_list args;
  va_start(args, fmt);
  fprintf(stderr, "%s: ", c->member_id);
  vfprintf(stderr, fmt, args);
  fputc('\n', stderr);
  va_end(args);
}

static void log_error(const controller* c, const char* fmt, ...) {
  va_list args;
  va_start(args, fmt);
  fprintf(stderr, "%s: error: ", c->member_id);
  vfprintf(stderr, fmt, args);
  fputc('\n', stderr);
  va_end(args);
}

static void fail(controller* c, const char* fmt, ...) {
  if (c->failure[0]) return; /* the first cause is the one reported */
  va_list args;
  va_start(args, fmt);
  vsnprintf(c->failure, sizeof c->failure, fmt, args);
  va_end(args);
}

/* ---- DDS setup --------------------------------------------------------------------------- */

/* CycloneDDS configuration: participant lease 2 s and announcements every 0.5 s (as the syndds
 * programs: CycloneDDS's default lease of 10 s would let a dead controller go unnoticed for
 * 10 s), optionally one network interface with multicast. The user's CYCLONEDDS_URI comes
 * after it and so overrides it. */
static char* build_config(const options* o) {
  char interfaces[NAME_SIZE + 128] = "";
  if (o->interface_name) {
    snprintf(interfaces, sizeof interfaces,
             "<General><Interfaces><NetworkInterface name=\"%s\" multicast=\"true\"/>"
             "</Interfaces><AllowMulticast>true</AllowMulticast></General>",
             o->interface_name);
  }
  const char* user = getenv("CYCLONEDDS_URI");
  const size_t size = 1024 + strlen(interfaces) + (user ? strlen(user) : 0);
  char* config = malloc(size);
  if (!config) return NULL;
  snprintf(config, size,
           "<CycloneDDS><Domain Id=\"any\">%s<Discovery><LeaseDuration>" LEASE_DURATION
           "</LeaseDuration><SPDPInterval>" SPDP_INTERVAL
           "</SPDPInterval></Discovery></Domain></CycloneDDS>%s%s",
           interfaces, (user && *user) ? "," : "", (user && *user) ? user : "");
  return config;
}

/* QoS of config/dds/profiles.xml: RELIABLE, TRANSIENT_LOCAL, KEEP_LAST 8 per key on writers
 * and 64 on readers. CycloneDDS replays to a late-matching reader only the durability-service
 * history (default KEEP_LAST 1), so that is set to the writer's depth too. */
static dds_qos_t* writer_qos(void) {
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, WRITER_DEPTH);
  dds_qset_durability_service(q, 0, DDS_HISTORY_KEEP_LAST, WRITER_DEPTH, DDS_LENGTH_UNLIMITED,
                              DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED);
  return q;
}

static dds_qos_t* reader_qos(void) {
  dds_qos_t* q = dds_create_qos();
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, READER_DEPTH);
  return q;
}

static dds_entity_t partitioned(dds_entity_t participant, bool publisher, uint32_t n,
                                const char** names) {
  dds_qos_t* q = dds_create_qos();
  dds_qset_partition(q, n, names);
  const dds_entity_t e = publisher ? dds_create_publisher(participant, q, NULL)
                                   : dds_create_subscriber(participant, q, NULL);
  dds_delete_qos(q);
  return e;
}

static bool check_entity(controller* c, dds_entity_t e, const char* what) {
  if (e >= 0) return true;
  fail(c, "DDS: cannot create %s: %s", what, dds_strretcode(e));
  return false;
}

/* Readers first, then writers (nothing addressed to us is missed). Returns 0 on success, or an
 * exit status. */
static int setup_dds(controller* c) {
  char* config = build_config(&c->opt);
  if (!config) {
    log_error(c, "out of memory");
    return EXIT_FAILED;
  }
  const dds_entity_t domain = dds_create_domain((dds_domainid_t)c->opt.domain, config);
  free(config);
  if (domain < 0) {
    log_error(c, "CycloneDDS rejected its configuration for domain %d: %s (check --interface "
                 "and CYCLONEDDS_URI)",
              c->opt.domain, dds_strretcode(domain));
    return EXIT_BAD_CONFIG;
  }
  c->participant = dds_create_participant((dds_domainid_t)c->opt.domain, NULL, NULL);
  if (c->participant < 0) {
    log_error(c, "cannot create a DDS participant on domain %d: %s", c->opt.domain,
              dds_strretcode(c->participant));
    return EXIT_BAD_CONFIG;
  }
  dds_guid_t guid;
  if (dds_get_guid(c->participant, &guid) != DDS_RETCODE_OK) {
    log_error(c, "cannot read the participant's GUID");
    return EXIT_FAILED;
  }
  format_guid_prefix(guid.v, c->own_guid, sizeof c->own_guid);

  char all[NAME_SIZE * 2], mine[NAME_SIZE * 2];
  snprintf(all, sizeof all, "%s/all", c->opt.run_id);
  snprintf(mine, sizeof mine, "%s/vehicle/%s", c->opt.run_id, c->opt.vehicle);
  const char* protocol_partition[] = {c->opt.run_id};
  const char* data_pub_partitions[] = {all, mine};
  const char* data_sub_partition[] = {mine};
  const dds_entity_t protocol_pub = partitioned(c->participant, true, 1, protocol_partition);
  const dds_entity_t protocol_sub = partitioned(c->participant, false, 1, protocol_partition);
  const dds_entity_t data_pub = partitioned(c->participant, true, 2, data_pub_partitions);
  const dds_entity_t data_sub = partitioned(c->participant, false, 1, data_sub_partition);
  if (!check_entity(c, protocol_pub, "the protocol publisher") ||
      !check_entity(c, protocol_sub, "the protocol subscriber") ||
      !check_entity(c, data_pub, "the data publisher") ||
      !check_entity(c, data_sub, "the data subscriber")) {
    return EXIT_FAILED;
  }

  const dds_entity_t t_announce = dds_create_topic(
      c->participant, &syndds_msg_MemberAnnounce_desc, "syndds/member_announce", NULL, NULL);
  const dds_entity_t t_grant = dds_create_topic(c->participant, &syndds_msg_FrameGrant_desc,
                                                "syndds/frame_grant", NULL, NULL);
  const dds_entity_t t_done = dds_create_topic(c->participant, &syndds_msg_FrameDone_desc,
                                               "syndds/frame_done", NULL, NULL);
  const dds_entity_t t_control = dds_create_topic(c->participant, &syndds_msg_RunControl_desc,
                                                  "syndds/run_control", NULL, NULL);
  const dds_entity_t t_state = dds_create_topic(c->participant, &syndds_msg_VehicleState_desc,
                                                "syndds/vehicle_state", NULL, NULL);
  const dds_entity_t t_command = dds_create_topic(
      c->participant, &syndds_msg_DriverCommand_desc, "syndds/driver_command", NULL, NULL);
  if (!check_entity(c, t_announce, "topic syndds/member_announce") ||
      !check_entity(c, t_grant, "topic syndds/frame_grant") ||
      !check_entity(c, t_done, "topic syndds/frame_done") ||
      !check_entity(c, t_control, "topic syndds/run_control") ||
      !check_entity(c, t_state, "topic syndds/vehicle_state") ||
      !check_entity(c, t_command, "topic syndds/driver_command")) {
    return EXIT_FAILED;
  }

  dds_qos_t* rq = reader_qos();
  c->announce_reader = dds_create_reader(protocol_sub, t_announce, rq, NULL);
  c->grant_reader = dds_create_reader(protocol_sub, t_grant, rq, NULL);
  c->control_reader = dds_create_reader(protocol_sub, t_control, rq, NULL);
  c->state_reader = dds_create_reader(data_sub, t_state, rq, NULL);
  dds_delete_qos(rq);
  /* Remote participants come and go here: the coordinator's loss (lease expired or left). */
  c->participant_reader =
      dds_create_reader(c->participant, DDS_BUILTIN_TOPIC_DCPSPARTICIPANT, NULL, NULL);
  if (!check_entity(c, c->announce_reader, "the member_announce reader") ||
      !check_entity(c, c->grant_reader, "the frame_grant reader") ||
      !check_entity(c, c->control_reader, "the run_control reader") ||
      !check_entity(c, c->state_reader, "the vehicle_state reader") ||
      !check_entity(c, c->participant_reader, "the DCPSParticipant reader")) {
    return EXIT_FAILED;
  }

  dds_qos_t* wq = writer_qos();
  c->command_writer = dds_create_writer(data_pub, t_command, wq, NULL);
  c->done_writer = dds_create_writer(protocol_pub, t_done, wq, NULL);
  c->announce_writer = dds_create_writer(protocol_pub, t_announce, wq, NULL);
  dds_delete_qos(wq);
  if (!check_entity(c, c->command_writer, "the driver_command writer") ||
      !check_entity(c, c->done_writer, "the frame_done writer") ||
      !check_entity(c, c->announce_writer, "the member_announce writer")) {
    return EXIT_FAILED;
  }

  /* One waitset wakes the main loop for every reader with data. */
  c->waitset = dds_create_waitset(c->participant);
  if (!check_entity(c, c->waitset, "a waitset")) return EXIT_FAILED;
  const dds_entity_t readers[] = {c->announce_reader, c->grant_reader, c->control_reader,
                                  c->state_reader, c->participant_reader};
  for (size_t i = 0; i < sizeof readers / sizeof readers[0]; ++i) {
    const dds_entity_t cond = dds_create_readcondition(readers[i], DDS_ANY_STATE);
    if (!check_entity(c, cond, "a read condition")) return EXIT_FAILED;
    if (dds_waitset_attach(c->waitset, cond, readers[i]) != DDS_RETCODE_OK) {
      fail(c, "DDS: cannot attach a read condition to the waitset");
      return EXIT_FAILED;
    }
  }
  return 0;
}

/* ---- receiving --------------------------------------------------------------------------- */

typedef void (*sample_fn)(controller* c, const void* sample, const dds_sample_info_t* info);

/* Takes everything a reader holds (loaned samples) and hands it to `fn`. */
static void take_all(controller* c, dds_entity_t reader, sample_fn fn) {
  void* samples[TAKE_BATCH];
  dds_sample_info_t infos[TAKE_BATCH];
  while (1) {
    memset(samples, 0, sizeof samples);
    const dds_return_t n = dds_take(reader, samples, infos, TAKE_BATCH, TAKE_BATCH);
    if (n <= 0) return;
    for (dds_return_t i = 0; i < n; ++i) fn(c, samples[i], &infos[i]);
    dds_return_loan(reader, samples, n);
    if (n < TAKE_BATCH) return;
  }
}

static bool guid_is_lost(const controller* c, const char* guid) {
  for (size_t i = 0; i < c->lost_count; ++i) {
    if (strcmp(c->lost_guids[i], guid) == 0) return true;
  }
  return false;
}

/* Admission: the coordinator lists "MEMBER PARTICIPANT" of each admitted member and
 * "MEMBER PARTICIPANT why" of each refused claimant. */
static bool entry_is_us(const controller* c, const char* entry, const char** rest) {
  const size_t m = strlen(c->member_id), g = strlen(c->own_guid);
  if (!entry || strncmp(entry, c->member_id, m) != 0 || entry[m] != ' ') return false;
  if (strncmp(entry + m + 1, c->own_guid, g) != 0) return false;
  const char end = entry[m + 1 + g];
  if (end != '\0' && end != ' ') return false;
  if (rest) *rest = end == ' ' ? entry + m + 2 + g : "";
  return true;
}

static void note_admission(controller* c, const syndds_msg_MemberAnnounce* a) {
  for (uint32_t i = 0; i < a->admitted._length; ++i) {
    if (entry_is_us(c, a->admitted._buffer[i], NULL)) c->admitted = true;
  }
  for (uint32_t i = 0; i < a->refused._length; ++i) {
    const char* why = NULL;
    if (entry_is_us(c, a->refused._buffer[i], &why) && !c->refused) {
      c->refused = true;
      snprintf(c->refusal, sizeof c->refusal, "%s", why);
    }
  }
}

/* The start time (field 22 of /proc/PID/stat) of process `pid`; 0 when it does not exist or
 * has ended (a zombie, state Z or X, waiting for its parent). */
static unsigned long long process_start(int pid) {
  char path[64], stat[1024] = "";
  snprintf(path, sizeof path, "/proc/%d/stat", pid);
  FILE* f = fopen(path, "r");
  if (!f) return 0;
  const bool got = fgets(stat, sizeof stat, f) != NULL;
  fclose(f);
  if (!got) return 0;
  const char* p = strrchr(stat, ')'); /* the command name may hold spaces */
  if (!p || p[1] != ' ' || p[2] == 'Z' || p[2] == 'X') return 0;
  for (int field = 2; field < 22 && p; ++field) p = strchr(p + 1, ' ');
  unsigned long long start = 0;
  if (!p || sscanf(p + 1, "%llu", &start) != 1) return 0;
  return start;
}

/* Watches the coordinator's process when its process_key ("BOOT_ID/PID/START") names this
 * machine's boot: it is lost when that process is gone, whatever its DDS lease says. */
static void watch_coordinator(controller* c, const char* key) {
  char boot[64] = "";
  FILE* f = fopen("/proc/sys/kernel/random/boot_id", "r");
  if (!f) return;
  const bool got = fgets(boot, sizeof boot, f) != NULL;
  fclose(f);
  if (!got) return;
  boot[strcspn(boot, "\n")] = '\0';
  const size_t n = strlen(boot);
  int pid = 0;
  unsigned long long start = 0;
  if (n == 0 || strncmp(key, boot, n) != 0 || key[n] != '/' ||
      sscanf(key + n + 1, "%d/%llu", &pid, &start) != 2 || pid <= 0) {
    return; /* another machine (or no key): the DDS lease tells */
  }
  c->coordinator_watch_pid = pid;
  c->coordinator_watch_start = start;
}

static void check_coordinator_process(controller* c) {
  if (c->coordinator_watch_pid <= 0 || c->coordinator_lost) return;
  if (process_start(c->coordinator_watch_pid) != c->coordinator_watch_start) {
    c->coordinator_lost = true;
  }
}

static void on_announce(controller* c, const void* sample, const dds_sample_info_t* info) {
  const syndds_msg_MemberAnnounce* a = sample;
  if (!info->valid_data || a->kind != syndds_msg_MEMBER_COORDINATOR) return;
  const char* guid = a->participant_guid ? a->participant_guid : "";
  if (c->coordinator_known) {
    if (strcmp(c->coordinator_guid, guid) != 0) {
      fail(c, "a second coordinator (pid %" PRId32 " on %s) announced run '%s'", a->pid,
           a->host ? a->host : "?", c->opt.run_id);
      return;
    }
    note_admission(c, a); /* its newest word on who is which member */
    return;
  }
  if (strlen(guid) >= sizeof c->coordinator_guid) {
    fail(c, "received a malformed member_announce sample: participant_guid too long");
    return;
  }
  c->coordinator_known = true;
  strcpy(c->coordinator_guid, guid);
  if (!copy_name(c->coordinator_host, a->host)) strcpy(c->coordinator_host, "?");
  c->coordinator_pid = a->pid;
  c->coordinator_protocol = a->protocol_version;
  c->coordinator_fingerprint = a->config_fingerprint;
  c->expects_us = false;
  for (uint32_t i = 0; i < a->expected_members._length; ++i) {
    const char* m = a->expected_members._buffer[i];
    if (m && strcmp(m, c->member_id) == 0) c->expects_us = true;
  }
  if (guid_is_lost(c, guid)) c->coordinator_lost = true;
  c->coordinator_frame_timeout_s = a->frame_timeout_s;
  c->coordinator_checkpoint_every = a->checkpoint_every;
  watch_coordinator(c, a->process_key ? a->process_key : "");
  note_admission(c, a);
}

static void on_participant(controller* c, const void* sample, const dds_sample_info_t* info) {
  const dds_builtintopic_participant_t* p = sample;
  if (info->instance_state == DDS_IST_ALIVE) return;
  char guid[64];
  format_guid_prefix(p->key.v, guid, sizeof guid);
  if (c->coordinator_known) {
    if (strcmp(guid, c->coordinator_guid) == 0) c->coordinator_lost = true;
  } else if (c->lost_count < MAX_LOST && !guid_is_lost(c, guid)) {
    strcpy(c->lost_guids[c->lost_count++], guid);
  }
}

static bool finite3(const syndds_msg_Vec3* v) {
  return isfinite(v->x) && isfinite(v->y) && isfinite(v->z);
}

static void on_state(controller* c, const void* sample, const dds_sample_info_t* info) {
  const syndds_msg_VehicleState* s = sample;
  if (!info->valid_data) return;
  if (!s->vehicle_id || strcmp(s->vehicle_id, c->opt.vehicle) != 0) return;
  if (s->frame < c->next_frame - 1) return; /* older than anything still to come */
  const syndds_msg_Quat* q = &s->pose.orientation;
  if (!finite3(&s->pose.position) || !isfinite(q->w) || !isfinite(q->x) || !isfinite(q->y) ||
      !isfinite(q->z) || !finite3(&s->linear_velocity)) {
    fail(c, "received a malformed vehicle_state sample from %s stamped frame %" PRId64
            ": pose or linear_velocity is not finite",
         s->source ? s->source : "?", s->frame);
    return;
  }
  /* A free slot, else the oldest one. */
  size_t slot = 0;
  for (size_t i = 0; i < MAX_STATES; ++i) {
    if (!c->states[i].used) {
      slot = i;
      break;
    }
    if (c->states[i].frame < c->states[slot].frame) slot = i;
  }
  stored_state* st = &c->states[slot];
  st->used = true;
  st->frame = s->frame;
  if (!copy_name(st->source, s->source)) strcpy(st->source, "?");
  st->x = s->pose.position.x;
  st->y = s->pose.position.y;
  st->yaw = pursuit_yaw(q->w, q->x, q->y, q->z);
  st->forward_speed = s->linear_velocity.x * cos(st->yaw) + s->linear_velocity.y * sin(st->yaw);
}

static void on_grant(controller* c, const void* sample, const dds_sample_info_t* info) {
  const syndds_msg_FrameGrant* g = sample;
  if (!info->valid_data) return;
  /* Grants of frames already done (replayed by TRANSIENT_LOCAL, or repeated) are ignored. */
  if (g->frame < c->next_frame) return;
  if (c->grant_count == MAX_PENDING_GRANTS) {
    if (c->admitted) {
      fail(c, "protocol error: more than %d grants pending", MAX_PENDING_GRANTS);
      return;
    }
    /* Not admitted yet: a run under way replays its last grants; only the newest matter. */
    c->grant_head = (c->grant_head + 1) % MAX_PENDING_GRANTS;
    --c->grant_count;
  }
  pending_grant* p = &c->grants[(c->grant_head + c->grant_count) % MAX_PENDING_GRANTS];
  memset(p, 0, sizeof *p);
  p->frame = g->frame;
  p->sim_time_s = g->sim_time_s;
  p->epoch = g->epoch;
  p->rollback = g->rollback;
  for (uint32_t i = 0; i < g->rejoined._length; ++i) {
    if (entry_is_us(c, g->rejoined._buffer[i], NULL)) p->rejoined_us = true;
  }
  for (uint32_t i = 0; i < g->manifest._length; ++i) {
    const syndds_msg_TopicCount* t = &g->manifest._buffer[i];
    if (!t->topic || !t->key || strcmp(t->topic, "vehicle_state") != 0 ||
        strcmp(t->key, c->opt.vehicle) != 0) {
      continue; /* not something this controller subscribes to */
    }
    if (p->needed_count == MAX_NEEDED || !copy_name(p->needed[p->needed_count].writer,
                                                    t->writer)) {
      fail(c, "received a malformed frame_grant sample for frame %" PRId64
              ": too many or too long vehicle_state entries",
           g->frame);
      return;
    }
    p->needed[p->needed_count++].count = t->count;
  }
  ++c->grant_count;
}

static void on_control(controller* c, const void* sample, const dds_sample_info_t* info) {
  const syndds_msg_RunControl* r = sample;
  if (!info->valid_data || c->control_received) return;
  c->control_received = true;
  c->control_status = (int32_t)r->status;
  c->control_final_frame = r->final_frame;
  snprintf(c->control_reason, sizeof c->control_reason, "%s", r->reason ? r->reason : "");
}

/* ---- sending ----------------------------------------------------------------------------- */

static bool send_done(controller* c, int64_t frame, bool published_command, double compute_s,
                      bool finished, const char* error, uint64_t checkpoint_bytes) {
  syndds_msg_TopicCount entry;
  entry.topic = "driver_command";
  entry.key = (char*)c->opt.vehicle;
  entry.writer = c->member_id;
  entry.count = 1;
  syndds_msg_FrameDone d;
  memset(&d, 0, sizeof d);
  d.member_id = c->member_id;
  d.frame = frame;
  d.published._length = published_command ? 1 : 0;
  d.published._maximum = d.published._length;
  d.published._buffer = published_command ? &entry : NULL;
  d.published._release = false;
  d.compute_s = compute_s;
  d.finished = finished;
  d.error = (char*)(error ? error : "");
  d.checkpoint_bytes = checkpoint_bytes;
  d.epoch = c->epoch;
  return dds_write(c->done_writer, &d) == DDS_RETCODE_OK;
}

/* "BOOT_ID/PID/START_TICKS" (proc(5): /proc/sys/kernel/random/boot_id, field 22 of
   /proc/self/stat): lets a coordinator on the same machine watch this process directly, so
   its exit is seen at once and a stall (load, a debugger) is not taken for death. Empty when
   /proc cannot tell; the coordinator then relies on the DDS lease alone. */
static void process_key(char* out, size_t size) {
  char boot[64] = "", stat[1024] = "";
  out[0] = '\0';
  FILE* f = fopen("/proc/sys/kernel/random/boot_id", "r");
  if (!f) return;
  const bool got_boot = fgets(boot, sizeof boot, f) != NULL;
  fclose(f);
  f = fopen("/proc/self/stat", "r");
  if (!f) return;
  const bool got_stat = fgets(stat, sizeof stat, f) != NULL;
  fclose(f);
  if (!got_boot || !got_stat) return;
  boot[strcspn(boot, "\n")] = '\0';
  const char* p = strrchr(stat, ')'); /* the command name may hold spaces */
  if (!p) return;
  /* After ')': field 3 (state) ... field 22 (starttime). */
  for (int field = 2; field < 22 && p; ++field) p = strchr(p + 1, ' ');
  if (!p) return;
  unsigned long long start = 0;
  if (sscanf(p + 1, "%llu", &start) != 1) return;
  snprintf(out, size, "%s/%d/%llu", boot, (int)getpid(), start);
}

static bool announce(controller* c) {
  char host[NAME_SIZE] = "unknown";
  if (gethostname(host, sizeof host - 1) != 0) strcpy(host, "unknown");
  host[sizeof host - 1] = '\0';
  syndds_msg_MemberAnnounce a;
  memset(&a, 0, sizeof a);
  a.member_id = c->member_id;
  a.kind = syndds_msg_MEMBER_EXTERNAL;
  a.run_id = (char*)c->opt.run_id;
  a.participant_guid = c->own_guid;
  a.host = host;
  a.pid = (int32_t)getpid();
  char key[160];
  process_key(key, sizeof key);
  a.process_key = key;
  a.protocol_version = PROTOCOL_VERSION;
  a.build_id = (char*)""; /* not a syndds build: unchecked */
  a.config_fingerprint = c->coordinator_fingerprint;
  return dds_write(c->announce_writer, &a) == DDS_RETCODE_OK;
}

/* ---- frames ------------------------------------------------------------------------------ */

static const stored_state* find_state(const controller* c, int64_t frame, const char* writer) {
  for (size_t i = 0; i < MAX_STATES; ++i) {
    const stored_state* s = &c->states[i];
    if (s->used && s->frame == frame && strcmp(s->source, writer) == 0) return s;
  }
  return NULL;
}

/* True when every vehicle state the grant announces (stamped frame - 1) is here. */
static bool inputs_complete(const controller* c, const pending_grant* g, char* missing,
                            size_t size) {
  for (size_t i = 0; i < g->needed_count; ++i) {
    uint32_t have = 0;
    for (size_t j = 0; j < MAX_STATES; ++j) {
      const stored_state* s = &c->states[j];
      if (s->used && s->frame == g->frame - 1 && strcmp(s->source, g->needed[i].writer) == 0) {
        ++have;
      }
    }
    if (have < g->needed[i].count) {
      if (missing) {
        snprintf(missing, size, "vehicle_state key=%s from %s: have %" PRIu32 " of %" PRIu32,
                 c->opt.vehicle, g->needed[i].writer, have, g->needed[i].count);
      }
      return false;
    }
  }
  return true;
}

/* ---- checkpoints ------------------------------------------------------------------------- */

/* A checkpoint of frame K is this controller's state after frame K and the input of frame
 * K + 1 (the vehicle state stamped K), as text: doubles with 17 significant digits come back
 * bit for bit. One file per frame, written whole (temporary file, then rename). */
static void checkpoint_path(const controller* c, int64_t frame, char* out, size_t size) {
  snprintf(out, size, "%s/external_%s-%" PRId64 ".state", c->opt.checkpoint_dir, c->opt.vehicle,
           frame);
}

static uint64_t save_checkpoint(controller* c, int64_t frame, const stored_state* input) {
  if (!c->opt.checkpoint_dir) {
    if (!c->warned_no_checkpoint_dir) {
      log_error(c, "the run takes checkpoints every %" PRId64 " frames but this controller has "
                   "no --checkpoint-dir: the run's checkpoints will be incomplete",
                c->coordinator_checkpoint_every);
      c->warned_no_checkpoint_dir = true;
    }
    return 0;
  }
  char path[1200], temp[1300];
  checkpoint_path(c, frame, path, sizeof path);
  snprintf(temp, sizeof temp, "%s.tmp", path);
  FILE* f = fopen(temp, "w");
  if (!f) {
    fail(c, "checkpoint of frame %" PRId64 ": cannot write %s: %s", frame, temp, strerror(errno));
    return 0;
  }
  fprintf(f, "syndds_cyclone_controller checkpoint 1\nframe %" PRId64 "\nmember %s\n", frame,
          c->member_id);
  fprintf(f, "segment %zu\nprogress_m %.17g\n", c->pursuit.segment, c->pursuit.progress_m);
  fprintf(f, "frames_done %" PRId64 "\ncommands_sent %" PRId64 "\nlast %.17g %.17g\n",
          c->frames_done, c->commands_sent, c->last_x, c->last_y);
  if (input) {
    fprintf(f, "input 1 %" PRId64 " %s %.17g %.17g %.17g %.17g\n", input->frame, input->source,
            input->x, input->y, input->yaw, input->forward_speed);
  } else {
    fprintf(f, "input 0\n");
  }
  const long size = ftell(f);
  const bool ok = fflush(f) == 0 && fsync(fileno(f)) == 0;
  if (fclose(f) != 0 || !ok || size <= 0 || rename(temp, path) != 0) {
    fail(c, "checkpoint of frame %" PRId64 ": cannot write %s: %s", frame, path, strerror(errno));
    return 0;
  }
  return (uint64_t)size;
}

/* Restores the checkpoint of `frame`; false (with a failure) when it is missing or malformed. */
static bool restore_checkpoint(controller* c, int64_t frame) {
  char path[1200];
  if (!c->opt.checkpoint_dir) {
    fail(c, "rollback to the checkpoint of frame %" PRId64 ": no --checkpoint-dir", frame);
    return false;
  }
  checkpoint_path(c, frame, path, sizeof path);
  FILE* f = fopen(path, "r");
  if (!f) {
    fail(c, "rollback to the checkpoint of frame %" PRId64 ": cannot read %s: %s", frame, path,
         strerror(errno));
    return false;
  }
  int version = 0, has_input = 0;
  int64_t saved_frame = -1;
  char member[NAME_SIZE] = "";
  stored_state in;
  memset(&in, 0, sizeof in);
  pursuit_state p;
  int64_t frames_done = 0, commands_sent = 0;
  double last_x = 0.0, last_y = 0.0;
  bool ok = fscanf(f, "syndds_cyclone_controller checkpoint %d frame %" SCNd64 " member %255s",
                   &version, &saved_frame, member) == 3 &&
            fscanf(f, " segment %zu progress_m %lf", &p.segment, &p.progress_m) == 2 &&
            fscanf(f, " frames_done %" SCNd64 " commands_sent %" SCNd64 " last %lf %lf",
                   &frames_done, &commands_sent, &last_x, &last_y) == 4 &&
            fscanf(f, " input %d", &has_input) == 1;
  if (ok && has_input) {
    ok = fscanf(f, " %" SCNd64 " %255s %lf %lf %lf %lf", &in.frame, in.source, &in.x, &in.y,
                &in.yaw, &in.forward_speed) == 6;
  }
  fclose(f);
  if (!ok || version != 1 || saved_frame != frame || strcmp(member, c->member_id) != 0) {
    fail(c, "rollback to the checkpoint of frame %" PRId64 ": %s is not a checkpoint of %s at "
            "that frame",
         frame, path, c->member_id);
    return false;
  }
  c->pursuit = p;
  c->frames_done = frames_done;
  c->commands_sent = commands_sent;
  c->last_x = last_x;
  c->last_y = last_y;
  in.used = true;
  c->resumed_input = in;
  c->resumed_has_state = has_input != 0;
  c->has_resumed_input = true;
  return true;
}

/* Every member restores its checkpoint of the granted frame and reports it done in the new
 * epoch; the next frame is then stepped with the input saved there. */
static void roll_back(controller* c, const pending_grant* g) {
  if (!restore_checkpoint(c, g->frame)) return;
  c->epoch = g->epoch;
  c->next_frame = g->frame + 1;
  c->restored_from = g->frame;
  c->rejoined = true;
  c->waiting_frame = -1;
  for (size_t i = 0; i < MAX_STATES; ++i) {
    if (c->states[i].used && c->states[i].frame < g->frame) c->states[i].used = false;
  }
  if (!send_done(c, g->frame, false, 0.0, false, NULL, 0)) {
    fail(c, "rollback to frame %" PRId64 ": DDS refused a frame_done sample", g->frame);
    return;
  }
  log_info(c, "rolled back to the checkpoint of frame %" PRId64 " (epoch %" PRIu32 ")", g->frame,
           g->epoch);
}

static void run_frame(controller* c, const pending_grant* g) {
  const double t0 = now_s();
  const stored_state* s = NULL;
  if (c->has_resumed_input) {
    /* The first frame after a rollback: its input is the one saved in the checkpoint. */
    if (c->resumed_has_state) s = &c->resumed_input;
  } else if (g->needed_count > 0) {
    s = find_state(c, g->frame - 1, g->needed[0].writer);
  }
  /* The checkpoint of frame - 1 (not the one just restored: it exists): the state before this
   * frame and its input. */
  uint64_t checkpoint_bytes = 0;
  const int64_t every = c->coordinator_checkpoint_every;
  const int64_t of = g->frame - 1;
  if (every > 0 && of > 0 && of % every == 0 && of != c->restored_from) {
    checkpoint_bytes = save_checkpoint(c, of, s);
    if (c->failure[0]) return;
  }
  c->has_resumed_input = false;
  bool wrote = false;
  if (s) {
    const pursuit_command cmd = pursuit_update(&c->opt.control, &c->opt.path, &c->pursuit, s->x,
                                               s->y, s->yaw, s->forward_speed);
    syndds_msg_DriverCommand out;
    memset(&out, 0, sizeof out);
    out.vehicle_id = (char*)c->opt.vehicle;
    out.source = c->member_id;
    out.frame = g->frame;
    out.steering = cmd.steering;
    out.throttle = cmd.throttle;
    out.braking = cmd.braking;
    if (dds_write(c->command_writer, &out) != DDS_RETCODE_OK) {
      fail(c, "frame %" PRId64 ": DDS refused a driver_command sample", g->frame);
      return;
    }
    wrote = true;
    ++c->commands_sent;
    c->last_x = s->x;
    c->last_y = s->y;
  }
  /* Without a state (frame 0) there is nothing to steer by: nothing is written, and the
   * done message says so (an empty `published`). */
  if (!send_done(c, g->frame, wrote, now_s() - t0, false, NULL, checkpoint_bytes)) {
    fail(c, "frame %" PRId64 ": DDS refused a frame_done sample", g->frame);
    return;
  }
  ++c->frames_done;
  if (g->frame == 0) log_info(c, "frame 0 granted: the run has started");
  if (g->frame > 0 && g->frame % 500 == 0) {
    log_info(c, "frame %" PRId64 " (t = %.2f s): at (%.2f, %.2f), %.1f m along the path",
             g->frame, g->sim_time_s, c->last_x, c->last_y, c->pursuit.progress_m);
  }
  /* States older than the next frame's input are not needed any more. */
  for (size_t i = 0; i < MAX_STATES; ++i) {
    if (c->states[i].used && c->states[i].frame < g->frame) c->states[i].used = false;
  }
}

/* --input-timeout, else 3/4 of the coordinator's frame deadline (so that this member names
 * the missing input before the coordinator names this member). */
static double input_timeout(const controller* c) {
  if (c->opt.input_timeout_s > 0.0) return c->opt.input_timeout_s;
  return c->coordinator_frame_timeout_s > 0.0 ? 0.75 * c->coordinator_frame_timeout_s : 7.5;
}

/* Runs every pending grant whose inputs are complete; notes a deadline for the first that is
 * not. */
static void pop_grant(controller* c) {
  c->grant_head = (c->grant_head + 1) % MAX_PENDING_GRANTS;
  --c->grant_count;
}

static void pump(controller* c) {
  /* A rollback (a member was lost, on_member_loss: recover) voids every grant before it. */
  for (size_t k = c->grant_count; k-- > 0;) {
    const pending_grant* g = &c->grants[(c->grant_head + k) % MAX_PENDING_GRANTS];
    if (g->rollback && g->epoch > c->epoch && (!c->opt.rejoin || c->rejoined || g->rejoined_us)) {
      c->grant_head = (c->grant_head + k) % MAX_PENDING_GRANTS;
      c->grant_count -= k;
      break;
    }
  }
  while (c->grant_count > 0 && !c->failure[0]) {
    const pending_grant* g = &c->grants[c->grant_head];
    if (g->epoch < c->epoch) { /* an older epoch's grant, replayed */
      pop_grant(c);
      continue;
    }
    if (g->rollback && g->epoch > c->epoch) {
      if (c->opt.rejoin && !c->rejoined && !g->rejoined_us) { /* an earlier recovery's */
        pop_grant(c);
        continue;
      }
      const pending_grant grant = *g;
      pop_grant(c);
      roll_back(c, &grant);
      continue;
    }
    if (c->opt.rejoin && !c->rejoined) { /* restarted: waits for the rollback naming it */
      pop_grant(c);
      continue;
    }
    if (g->frame < c->next_frame) { /* a duplicate queued before its frame ran */
      c->grant_head = (c->grant_head + 1) % MAX_PENDING_GRANTS;
      --c->grant_count;
      continue;
    }
    if (g->frame > c->next_frame) {
      fail(c, "protocol error: granted frame %" PRId64 " while frame %" PRId64 " was expected",
           g->frame, c->next_frame);
      return;
    }
    char missing[512];
    if (!inputs_complete(c, g, missing, sizeof missing)) {
      if (c->waiting_frame != g->frame) {
        c->waiting_frame = g->frame;
        c->waiting_since = now_s();
      } else if (now_s() - c->waiting_since > input_timeout(c)) {
        fail(c, "frame %" PRId64 ": announced inputs missing after %g s: %s", g->frame,
             input_timeout(c), missing);
      }
      return;
    }
    const pending_grant grant = *g;
    c->grant_head = (c->grant_head + 1) % MAX_PENDING_GRANTS;
    --c->grant_count;
    run_frame(c, &grant);
    c->next_frame = grant.frame + 1;
  }
}

/* ---- the run ----------------------------------------------------------------------------- */

/* The checks a member makes on the coordinator's announcement. Returns false with a failure. */
static bool accept_coordinator(controller* c) {
  if (!c->expects_us) {
    fail(c, "the coordinator of run '%s' does not expect member %s (is vehicle '%s' "
            "`controller: {type: external}` in the scenario?)",
         c->opt.run_id, c->member_id, c->opt.vehicle);
    return false;
  }
  if (c->coordinator_protocol != PROTOCOL_VERSION) {
    fail(c, "protocol version mismatch: coordinator %" PRId32 ", mine %d",
         c->coordinator_protocol, PROTOCOL_VERSION);
    return false;
  }
  if (c->opt.has_fingerprint && c->opt.fingerprint != c->coordinator_fingerprint) {
    fail(c, "scenario mismatch: the coordinator (host %s) has fingerprint %" PRIu64
            ", --fingerprint says %" PRIu64,
         c->coordinator_host, c->coordinator_fingerprint, c->opt.fingerprint);
    return false;
  }
  return true;
}

/* The reply to RunControl: our last samples acknowledged, then FrameDone{finished}. */
static int finish(controller* c) {
  const bool completed = c->control_status == syndds_msg_RUN_COMPLETED;
  if (completed) {
    log_info(c, "run completed after frame %" PRId64 "; %" PRId64 " frames, %" PRId64
                " commands; last state at (%.2f, %.2f), %.1f m along the path",
             c->control_final_frame, c->frames_done, c->commands_sent, c->last_x, c->last_y,
             c->pursuit.progress_m);
  } else {
    log_error(c, "run aborted: %s", c->control_reason);
  }
  if (dds_wait_for_acks(c->command_writer, DDS_SECS(2)) != DDS_RETCODE_OK) {
    log_error(c, "not every reader acknowledged the last driver commands within 2 s");
  }
  /* The finished reply carries the run's final frame (RunControl.final_frame). */
  if (!send_done(c, c->control_final_frame, false, 0.0, true, NULL, 0) ||
      dds_wait_for_acks(c->done_writer, DDS_SECS(2)) != DDS_RETCODE_OK) {
    log_error(c, "could not confirm the end of the run to the coordinator");
  }
  return completed ? EXIT_COMPLETED : EXIT_ABORTED;
}

/* This process gives up: tell the coordinator why (the run's reason names it), then go. */
static int give_up(controller* c, int code) {
  log_error(c, "%s", c->failure);
  if (c->admitted && c->done_writer > 0 && !c->coordinator_lost) {
    if (send_done(c, c->next_frame, false, 0.0, false, c->failure, 0)) {
      dds_wait_for_acks(c->done_writer, DDS_SECS(1));
    }
  }
  return code;
}

static int run(controller* c) {
  const double join_deadline = now_s() + c->opt.join_timeout_s;
  log_info(c, "waiting for the coordinator of run '%s' on DDS domain %d (participant %s)",
           c->opt.run_id, c->opt.domain, c->own_guid);
  while (1) {
    dds_waitset_wait(c->waitset, NULL, 0, DDS_MSECS(50));
    take_all(c, c->announce_reader, on_announce);
    take_all(c, c->participant_reader, on_participant);
    take_all(c, c->state_reader, on_state);
    take_all(c, c->grant_reader, on_grant);
    take_all(c, c->control_reader, on_control);

    if (interrupted_flag) {
      log_error(c, "interrupted");
      return EXIT_INTERRUPTED;
    }
    if (c->failure[0]) return give_up(c, EXIT_FAILED);
    if (!c->joined) {
      if (!c->coordinator_known) {
        if (now_s() >= join_deadline) {
          fail(c, "no coordinator for run '%s' on DDS domain %d within %g s", c->opt.run_id,
               c->opt.domain, c->opt.join_timeout_s);
          return give_up(c, EXIT_FAILED);
        }
        continue;
      }
      if (!accept_coordinator(c)) return give_up(c, EXIT_FAILED);
      if (!announce(c)) {
        fail(c, "DDS refused the member_announce sample");
        return give_up(c, EXIT_FAILED);
      }
      c->joined = true;
      log_info(c, "joined run '%s' (coordinator pid %" PRId32 " on %s, fingerprint %" PRIu64
                  ")",
               c->opt.run_id, c->coordinator_pid, c->coordinator_host,
               c->coordinator_fingerprint);
    }
    check_coordinator_process(c);
    /* Admission: grants count only once the coordinator named this participant as the
     * member; a refused claimant (another participant is this member) ends, telling nobody. */
    if (c->refused) {
      log_error(c, "refused by the coordinator as %s: %s", c->member_id, c->refusal);
      return EXIT_REFUSED;
    }
    /* The end of the run before the coordinator's departure: it leaves right after it. */
    if (c->admitted && c->control_received) return finish(c);
    if (c->coordinator_lost) {
      fail(c, "the coordinator was lost (its process exited or stopped answering)");
      return give_up(c, EXIT_FAILED);
    }
    if (!c->admitted) continue;
    pump(c);
    if (c->failure[0]) return give_up(c, EXIT_FAILED);
  }
}

int main(int argc, char** argv) {
  controller* c = calloc(1, sizeof *c); /* large (grant and state buffers): not on the stack */
  if (!c) {
    fprintf(stderr, "syndds_cyclone_controller: out of memory\n");
    return EXIT_FAILED;
  }
  const int parsed = parse_options(argc, argv, &c->opt);
  if (parsed <= 0) {
    if (parsed < 0) usage(stdout);
    free(c);
    return parsed < 0 ? EXIT_COMPLETED : EXIT_BAD_CONFIG;
  }
  snprintf(c->member_id, sizeof c->member_id, "external/%s", c->opt.vehicle);
  c->waiting_frame = -1;
  c->restored_from = -1;
  pursuit_reset(&c->pursuit);
  setvbuf(stderr, NULL, _IOLBF, 0);

  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, NULL);
  sigaction(SIGTERM, &sa, NULL);

  int code = setup_dds(c);
  if (code == 0) {
    code = run(c);
  } else if (c->failure[0]) {
    log_error(c, "%s", c->failure);
  }
  /* Deleting the participant says goodbye: the others see it leave at once. Wait a moment
   * first, so that our acknowledgements of the coordinator's last messages go out (its
   * writers would otherwise wait for them). */
  if (c->participant > 0) {
    const struct timespec linger = {0, 100 * 1000 * 1000};
    nanosleep(&linger, NULL);
    dds_delete(c->participant);
  }
  free(c);
  return code;
}
