/* The C API compiled as C (C99): dvs/dvs.h must be a C header. Checks the calls that need no model: version, the
 * argument errors and their messages, a context, option defaults, and a job whose input is missing (its status and
 * message come back through dvs_job_result). Exit status 0 = every check passed. */
#include <stdio.h>
#include <string.h>

#include "dvs/dvs.h"

static int failures = 0;

#define CHECK(cond, ...)                          \
  do {                                            \
    if (!(cond)) {                                \
      ++failures;                                 \
      printf("FAIL %s:%d: ", __FILE__, __LINE__); \
      printf(__VA_ARGS__);                        \
      printf("\n");                               \
    }                                             \
  } while (0)

static void lock_nothing(void* user) { (void)user; }

static int contains(const char* text, const char* part) { return text && strstr(text, part) != NULL; }

int main(int argc, char** argv) {
  const char* dir = argc > 1 ? argv[1] : "/tmp";
  char path[1024];
  dvs_context* ctx = NULL;
  dvs_depth_estimator* estimator = NULL;
  dvs_render_options options;
  dvs_job* job = NULL;
  dvs_job_state state = DVS_JOB_RUNNING;
  dvs_status status;
  char name[256], error[1024];

  CHECK(strlen(dvs_version()) >= 5, "version \"%s\"", dvs_version());

  status = dvs_context_create(NULL, 0, NULL);
  CHECK(status == DVS_ERROR_INVALID_ARGUMENT, "NULL out: status %d", (int)status);
  CHECK(contains(dvs_last_error(), "dvs_context_create: out is NULL"), "message \"%s\"", dvs_last_error());

  {
    /* A host device with only one of the two queue-lock functions is refused before any Vulkan call. */
    dvs_host_device host;
    dvs_context* on_host = NULL;
    memset(&host, 0, sizeof host);
    host.lock_queue = lock_nothing;
    status = dvs_context_create_on_host(&host, &on_host);
    CHECK(status == DVS_ERROR_INVALID_ARGUMENT && on_host == NULL, "one lock function: status %d", (int)status);
    CHECK(contains(dvs_last_error(), "lock_queue and host->unlock_queue"), "message \"%s\"", dvs_last_error());
    status = dvs_context_create_on_host(NULL, &on_host);
    CHECK(status == DVS_ERROR_INVALID_ARGUMENT && contains(dvs_last_error(), "host is NULL"), "NULL host: %d %s",
          (int)status, dvs_last_error());
  }

  status = dvs_context_create(NULL, 0, &ctx);
  CHECK(status == DVS_OK && ctx != NULL, "dvs_context_create: %d %s", (int)status, dvs_last_error());
  if (!ctx) return 1;
  CHECK(dvs_context_device_name(ctx, name, sizeof name) == DVS_OK && name[0] != '\0', "device name");
  printf("device: %s\n", name);
  /* A buffer too small for the name is filled and terminated, not overrun. */
  name[3] = 'x';
  CHECK(dvs_context_device_name(ctx, name, 3) == DVS_OK && strlen(name) == 2 && name[3] == 'x', "truncation");

  snprintf(path, sizeof path, "%s/none.pth", dir);
  status = dvs_depth_estimator_create(ctx, path, 0, -1, &estimator);
  CHECK(status == DVS_ERROR_FILE && estimator == NULL, "missing model: status %d", (int)status);
  CHECK(contains(dvs_last_error(), "none.pth: no such depth model"), "message \"%s\"", dvs_last_error());
  status = dvs_depth_estimator_create(ctx, path, 0, 2, &estimator);
  CHECK(status == DVS_ERROR_INVALID_ARGUMENT && contains(dvs_last_error(), "metric must be"), "metric 2: %d %s",
        (int)status, dvs_last_error());

  CHECK(dvs_render_options_default(&options) == DVS_OK, "dvs_render_options_default");
  CHECK(options.frames == 49 && options.height == 480 && options.width == 720 &&
            strcmp(options.trajectory, "loop1") == 0 && options.depth_input_size == 518,
        "render defaults: %d %dx%d %s %d", options.frames, options.height, options.width, options.trajectory,
        options.depth_input_size);

  snprintf(path, sizeof path, "%s/missing.mp4", dir);
  options.video = path;
  options.depth = path;
  options.out_dir = dir;
  CHECK(dvs_job_start_render(&options, &job) == DVS_OK && job != NULL, "start: %s", dvs_last_error());
  status = dvs_job_result(job);
  CHECK(status == DVS_ERROR_FILE, "failing job: status %d", (int)status);
  CHECK(contains(dvs_last_error(), "missing.mp4"), "failing job: message \"%s\"", dvs_last_error());
  CHECK(dvs_job_poll(job, &state) == DVS_OK && state == DVS_JOB_FAILED, "failing job: state %d", (int)state);
  CHECK(dvs_job_error(job, error, sizeof error) == DVS_OK && contains(error, "missing.mp4"), "job error \"%s\"", error);
  CHECK(dvs_job_destroy(job) == DVS_OK, "dvs_job_destroy");
  CHECK(dvs_job_destroy(NULL) == DVS_OK, "destroying NULL");

  status = dvs_job_poll(NULL, &state);
  CHECK(status == DVS_ERROR_INVALID_ARGUMENT && contains(dvs_last_error(), "dvs_job_poll: job is NULL"),
        "NULL job: %d %s", (int)status, dvs_last_error());

  CHECK(dvs_context_destroy(ctx) == DVS_OK, "dvs_context_destroy");
  printf("%s\n", failures ? "FAILED" : "all checks passed");
  return failures ? 1 : 0;
}
