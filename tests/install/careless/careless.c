/* The installed C API under careless use (issue 34 §2), compiled as C99 against the installed dvs/dvs.h (which must
 * include only C headers) by tests/install/run_install_test.sh and run with the conformance pack's tiny model. Each
 * check prints "ok ..." or "FAIL ..."; exit status 0 = all passed.
 *
 *   careless_c MODEL_DIR CACHE_DIR */
#include <pthread.h>
#include <stdio.h>
#include <string.h>

#include "dvs/dvs.h"

#if !defined(DVS_VERSION_MAJOR) || !defined(DVS_VERSION_MINOR) || !defined(DVS_VERSION_PATCH)
#error "dvs/dvs.h defines no version macros"
#endif

enum { F = 9, H = 64, W = 64 };
static uint8_t frames[F * H * W * 3];
static float depth[F * H * W];
static uint8_t alone[F * H * W * 3];
static uint8_t renders[2][H * W * 4];
static const char *model, *cache;
static int failures = 0;

/* Prints the check; `detail` (the last error, usually) only for a failed one. */
static void check(int ok, const char* what, const char* detail) {
  printf("%s %s%s%s\n", ok ? "ok" : "FAIL", what, !ok && detail ? ": " : "", !ok && detail ? detail : "");
  if (!ok) ++failures;
}

static int has(const char* text, const char* part) { return strstr(text, part) != NULL; }

static void options(dvs_pipeline_options* o) {
  dvs_pipeline_options_default(o);
  o->model = model;
  o->prompt = "a red fox";
  o->steps = 4;
  o->inversion_steps = 3;
  o->render.frames = 0;
  o->render.height = H;
  o->render.width = W;
  o->render.metric_depth = 1;
  o->cache_dir = cache;
  o->use_cache = 0;
}

static dvs_status run(dvs_context* ctx, uint8_t* out) {
  dvs_pipeline_options o;
  options(&o);
  return dvs_run_pipeline_clip(ctx, &o, frames, F, H, W, depth, NULL, out, NULL, NULL, 0, NULL, NULL);
}

static dvs_scene* scene_on(dvs_context* ctx) {
  dvs_intrinsics k;
  dvs_scene_options so = {0, 0}; /* metric depth, soft splat */
  dvs_scene* s = NULL;
  dvs_intrinsics_default(W, H, 0, &k);
  if (dvs_scene_create(ctx, frames, DVS_U8, H, W, depth, &k, &so, &s) != DVS_OK) check(0, "scene", dvs_last_error());
  return s;
}

static dvs_status render(dvs_scene* s, int i, uint8_t* rgba) {
  double pose[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  pose[3] = i % 2 ? 0.05 : -0.03;
  return dvs_scene_render(s, pose, rgba, DVS_U8, NULL);
}

/* A job whose first progress event waits until the test says go (so "while the job runs" is certain). */
static volatile int started = 0, go = 0;
static pthread_mutex_t mutex = PTHREAD_MUTEX_INITIALIZER;
static pthread_cond_t changed = PTHREAD_COND_INITIALIZER;
static int held_progress(const char* stage, int32_t step, int32_t total, const char* note, void* user) {
  (void)stage, (void)step, (void)total, (void)note, (void)user;
  pthread_mutex_lock(&mutex);
  started = 1;
  pthread_cond_broadcast(&changed);
  while (!go) pthread_cond_wait(&changed, &mutex);
  pthread_mutex_unlock(&mutex);
  return 0;
}
static void set_go(int value) {
  pthread_mutex_lock(&mutex);
  go = value;
  started = value ? started : 0;
  pthread_cond_broadcast(&changed);
  pthread_mutex_unlock(&mutex);
}
static void wait_started(void) {
  pthread_mutex_lock(&mutex);
  while (!started) pthread_cond_wait(&changed, &mutex);
  pthread_mutex_unlock(&mutex);
}
/* A run on a thread of its own, with a progress callback (NULL: none; held_progress: held in its first event). */
struct threaded_run {
  dvs_context* ctx;
  uint8_t* out;
  dvs_progress_fn progress;
  dvs_status status;
};
static void* threaded_run_main(void* arg) {
  struct threaded_run* r = (struct threaded_run*)arg;
  dvs_pipeline_options o;
  options(&o);
  r->status = dvs_run_pipeline_clip(r->ctx, &o, frames, F, H, W, depth, NULL, r->out, NULL, NULL, 0, r->progress, NULL);
  return NULL;
}

int main(int argc, char** argv) {
  static uint8_t a[F * H * W * 3], b[F * H * W * 3], rgba[H * W * 4];
  static float latent[4096];
  char text[64];
  dvs_context *ctx = NULL, *preview = NULL;
  dvs_scene* scene = NULL;
  dvs_job* job = NULL;
  dvs_status s;
  size_t i, needed = 0;
  int same, n;
  if (argc != 3) {
    fprintf(stderr, "usage: careless_c MODEL_DIR CACHE_DIR\n");
    return 2;
  }
  model = argv[1], cache = argv[2];
  for (i = 0; i < sizeof frames; ++i) frames[i] = (uint8_t)((i * 7 + i / 192 * 11) % 256);
  for (i = 0; i < F * H * W; ++i) depth[i] = 2.0f + 0.5f * (float)(i % W + i / W % H) / (W + H) + 0.01f * (float)(i / (H * W));

  snprintf(text, sizeof text, "%d.%d.%d", DVS_VERSION_MAJOR, DVS_VERSION_MINOR, DVS_VERSION_PATCH);
  check(strcmp(text, dvs_version()) == 0, "DVS_VERSION_MAJOR/MINOR/PATCH equal dvs_version()", dvs_version());

  /* The references: a run and two renders alone. */
  if (dvs_context_create(NULL, 0, &ctx) != DVS_OK) return printf("FAIL context: %s\n", dvs_last_error()), 1;
  check(run(ctx, alone) == DVS_OK, "the run alone", dvs_last_error());
  scene = scene_on(ctx);
  check(render(scene, 0, renders[0]) == DVS_OK && render(scene, 1, renders[1]) == DVS_OK, "the renders alone", NULL);
  dvs_scene_destroy(scene);

  { /* §2.1: two threads call dvs_run_pipeline_clip on one context (segfaulted): serialised, both right */
    struct threaded_run other = {NULL, a, NULL, DVS_OK};
    pthread_t t;
    other.ctx = ctx;
    pthread_create(&t, NULL, threaded_run_main, &other);
    s = run(ctx, b);
    pthread_join(t, NULL);
    check(s == DVS_OK && other.status == DVS_OK && memcmp(a, alone, sizeof a) == 0 && memcmp(b, alone, sizeof b) == 0,
          "two threads on one context: both outputs equal the run alone", dvs_last_error());
  }

  { /* §2.1: a render and a run on the context a job runs on (segfaulted): refused, naming the job and the remedy */
    dvs_pipeline_options o;
    dvs_job_state state;
    options(&o);
    scene = scene_on(ctx);
    check(dvs_job_start_pipeline_clip(ctx, &o, frames, F, H, W, depth, NULL, a, NULL, NULL, 0, &job) == DVS_OK,
          "dvs_job_start_pipeline_clip", dvs_last_error());
    s = DVS_OK;
    /* Renders until one is refused (the job holds the context from its start: the first is) or the job ends. */
    for (n = 0; dvs_job_poll(job, &state) == DVS_OK && state == DVS_JOB_RUNNING && s == DVS_OK; ++n)
      s = render(scene, n, rgba);
    if (s != DVS_OK)
      check(s == DVS_ERROR_INVALID_ARGUMENT && has(dvs_last_error(), "pipeline job") &&
                has(dvs_last_error(), "dvs_context_create"),
            "a render on the job's context is refused naming the job and the remedy", dvs_last_error());
    else
      check(0, "a render on the job's context is refused", "the job ended before any render was refused");
    s = run(ctx, b);
    check(s == DVS_ERROR_INVALID_ARGUMENT || dvs_job_poll(job, &state) != DVS_OK || state != DVS_JOB_RUNNING,
          "a run on the job's context is refused", dvs_last_error());
    check(dvs_job_result(job) == DVS_OK && memcmp(a, alone, sizeof a) == 0, "the job is undisturbed", dvs_last_error());
    dvs_job_destroy(job);
    check(render(scene, 1, rgba) == DVS_OK && memcmp(rgba, renders[1], sizeof rgba) == 0,
          "the scene renders once the job has ended", dvs_last_error());
  }

  { /* §2.1: the preview on a second context of the same device renders beside a run held in its progress callback */
    struct threaded_run held = {NULL, a, held_progress, DVS_OK};
    pthread_t t;
    held.ctx = ctx;
    check(dvs_context_create(NULL, 0, &preview) == DVS_OK, "a second context", dvs_last_error());
    dvs_scene_destroy(scene);
    scene = scene_on(preview);
    set_go(0);
    pthread_create(&t, NULL, threaded_run_main, &held);
    wait_started();
    for (same = 1, n = 0; n < 6; ++n) same = same && render(scene, n, rgba) == DVS_OK && memcmp(rgba, renders[n % 2], sizeof rgba) == 0;
    set_go(1);
    pthread_join(t, NULL);
    check(same, "six renders on a second context during a run equal the renders alone", dvs_last_error());
    check(held.status == DVS_OK && memcmp(a, alone, sizeof a) == 0, "the run beside them", dvs_last_error());
  }

  { /* §2.2: dvs_context_destroy while a scene lives (the render aborted), and under a running job (segfaulted) */
    dvs_pipeline_options o;
    dvs_job_state state;
    check(dvs_context_destroy(preview) == DVS_OK, "dvs_context_destroy with a scene alive", dvs_last_error());
    check(render(scene, 0, rgba) == DVS_OK && memcmp(rgba, renders[0], sizeof rgba) == 0,
          "the scene renders after its context was destroyed", dvs_last_error());
    check(dvs_scene_destroy(scene) == DVS_OK, "dvs_scene_destroy after its context", dvs_last_error());
    options(&o);
    check(dvs_job_start_pipeline_clip(ctx, &o, frames, F, H, W, depth, NULL, a, NULL, NULL, 0, &job) == DVS_OK,
          "a job to destroy the context under", dvs_last_error());
    check(dvs_context_destroy(ctx) == DVS_OK, "dvs_context_destroy under a running job", dvs_last_error());
    check(dvs_job_poll(job, &state) == DVS_OK && state == DVS_JOB_CANCELLED,
          "destroying the context cancelled its job and waited for its end", NULL);
    check(dvs_job_result(job) == DVS_ERROR_CANCELLED, "the job's result is DVS_ERROR_CANCELLED", dvs_last_error());
    dvs_job_destroy(job);
  }

  { /* §2.9: status codes */
    dvs_pipeline_options o;
    int32_t reached = 0;
    double bad_pose[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0.1, 1};
    char five[5];
    size_t want = 0;
    check(dvs_context_create(NULL, 0, &ctx) == DVS_OK, "a context", dvs_last_error());
    scene = scene_on(ctx);
    s = dvs_context_wait(ctx, 1000, 0, &reached);
    check(s == DVS_ERROR_INVALID_ARGUMENT, "a wait on a ticket never submitted is DVS_ERROR_INVALID_ARGUMENT", dvs_last_error());
    s = dvs_scene_render(scene, bad_pose, rgba, DVS_U8, NULL);
    check(s == DVS_ERROR_INVALID_ARGUMENT, "a bad pose is DVS_ERROR_INVALID_ARGUMENT", dvs_last_error());
    dvs_context_requirements(0, NULL, 0, &want);
    s = dvs_context_requirements(0, five, sizeof five, &needed);
    check(s == DVS_ERROR_INVALID_ARGUMENT && needed == want && needed > sizeof five && five[4] == '\0',
          "dvs_context_requirements with 5 bytes says the size it needs", dvs_last_error());
    options(&o);
    s = dvs_run_pipeline_clip(ctx, &o, frames, 8, H, W, depth, NULL, a, NULL, latent, 1000, NULL, NULL);
    check(s == DVS_ERROR_INVALID_ARGUMENT && has(dvs_last_error(), "8 is not 4k+1"), "8 frames name 4k+1 first",
          dvs_last_error());
    s = dvs_run_pipeline_clip(ctx, &o, frames, F, 60, 60, depth, NULL, a, NULL, latent, 1000, NULL, NULL);
    check(s == DVS_ERROR_INVALID_ARGUMENT && has(dvs_last_error(), "60x60") && has(dvs_last_error(), "multiples of 8"),
          "60x60 names the multiples of 8 first", dvs_last_error());
    o.preset = "fancy";
    s = dvs_run_pipeline_clip(ctx, &o, frames, F, H, W, depth, NULL, a, NULL, NULL, 0, NULL, NULL);
    check(s == DVS_ERROR_INVALID_ARGUMENT && has(dvs_last_error(), "fancy"), "a bad preset is DVS_ERROR_INVALID_ARGUMENT",
          dvs_last_error());
    dvs_scene_destroy(scene);
    {
      dvs_intrinsics k;
      dvs_intrinsics_default(1 << 20, 1 << 20, 0, &k);
      s = dvs_scene_create(ctx, frames, DVS_U8, 1 << 20, 1 << 20, depth, &k, NULL, &scene);
      check(s == DVS_ERROR_OUT_OF_MEMORY && scene == NULL, "a 2^20 x 2^20 scene is DVS_ERROR_OUT_OF_MEMORY",
            dvs_last_error());
    }
    dvs_context_destroy(ctx);
  }
  printf("%d check(s) failed\n", failures);
  return failures ? 1 : 0;
}
