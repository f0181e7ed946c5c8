/* A ROS 2 subscription as rmw_cyclonedds makes it, in plain C on Cyclone DDS (types from idlc -t:
 * no XTypes type information, as rmw_cyclonedds' own serdata).
 *
 * usage: cyclone_reader DOMAIN OUTDIR TIMEOUT_S KIND:DDS_TOPIC:COUNT...
 *   KIND grid | poses | info | entities (ros_discovery_info); the reader is reliable,
 *   transient-local, keep-last 1 (nav2's /map). KIND graph: DDS_TOPIC is a topic-name prefix and
 *   COUNT the number of remote writers on such topics to see; prints each writer (GUID, topic,
 *   type, USER_DATA) and each participant (GUID, USER_DATA) from DDS's built-in topics.
 * For each sample it prints one line (see print_* below) and, for grids, writes the cells to
 * OUTDIR/<spec index>.<sample number>.bin. Exit 0 when every topic got COUNT samples, 2 on timeout.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "dds/dds.h"
#include "ros2_msgs.h"

static double now_s(void) {
  struct timespec ts; clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void print_hex(const unsigned char *p, size_t n) {
  putchar(' ');
  for (size_t i = 0; i < n; i++) printf("%02x", p[i]);
}

static void print_user_data(const dds_qos_t *qos) {
  void *ud = NULL; size_t sz = 0;
  if (qos && dds_qget_userdata(qos, &ud, &sz) && sz > 0) printf(" %.*s", (int)sz, (char *)ud);
  else printf(" -");
  dds_free(ud);
}

static void print_pose(const geometry_msgs_msg_dds__Pose_ *p) {
  printf(" %.17g %.17g %.17g %.17g %.17g %.17g %.17g", p->position.x, p->position.y, p->position.z,
         p->orientation.x, p->orientation.y, p->orientation.z, p->orientation.w);
}

int main(int argc, char **argv) {
  double t0 = now_s();
  if (argc < 5) { fprintf(stderr, "usage: %s DOMAIN OUTDIR TIMEOUT_S KIND:TOPIC:COUNT...\n", argv[0]); return 1; }
  int domain = atoi(argv[1]); const char *outdir = argv[2]; double timeout = atof(argv[3]);
  int n = argc - 4;
  dds_entity_t *readers = calloc(n, sizeof *readers);
  int *kinds = calloc(n, sizeof *kinds), *want = calloc(n, sizeof *want), *got = calloc(n, sizeof *got);
  char **prefixes = calloc(n, sizeof *prefixes);
  dds_entity_t participants = 0;
  dds_entity_t dp = dds_create_participant(domain, NULL, NULL);
  if (dp < 0) { fprintf(stderr, "participant: %s\n", dds_strretcode(-dp)); return 1; }
  dds_qos_t *qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(10));
  dds_qset_durability(qos, DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 1);
  for (int i = 0; i < n; i++) {
    char spec[512]; strncpy(spec, argv[4 + i], sizeof spec - 1); spec[sizeof spec - 1] = 0;
    char *kind = strtok(spec, ":"), *topic = strtok(NULL, ":"), *count = strtok(NULL, ":");
    if (!kind || !topic || !count) { fprintf(stderr, "bad spec %s\n", argv[4 + i]); return 1; }
    const dds_topic_descriptor_t *desc;
    if (!strcmp(kind, "grid")) { kinds[i] = 0; desc = &nav_msgs_msg_dds__OccupancyGrid__desc; }
    else if (!strcmp(kind, "poses")) { kinds[i] = 1; desc = &geometry_msgs_msg_dds__PoseArray__desc; }
    else if (!strcmp(kind, "info")) { kinds[i] = 2; desc = &nav2_msgs_msg_dds__CostmapFilterInfo__desc; }
    else if (!strcmp(kind, "entities")) { kinds[i] = 3; desc = &rmw_dds_common_msg_dds__ParticipantEntitiesInfo__desc; }
    else if (!strcmp(kind, "graph")) { kinds[i] = 4; desc = NULL; }
    else { fprintf(stderr, "bad kind %s\n", kind); return 1; }
    want[i] = atoi(count);
    if (kinds[i] == 4) {  /* remote writers; participants are read below as they come */
      prefixes[i] = strdup(topic);
      readers[i] = dds_create_reader(dp, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, NULL, NULL);
      participants = dds_create_reader(dp, DDS_BUILTIN_TOPIC_DCPSPARTICIPANT, NULL, NULL);
      continue;
    }
    dds_entity_t tp = dds_create_topic(dp, desc, topic, NULL, NULL);
    if (tp < 0) { fprintf(stderr, "topic %s: %s\n", topic, dds_strretcode(-tp)); return 1; }
    readers[i] = dds_create_reader(dp, tp, qos, NULL);
    if (readers[i] < 0) { fprintf(stderr, "reader %s: %s\n", topic, dds_strretcode(-readers[i])); return 1; }
  }
  printf("READY\n"); fflush(stdout);
  for (;;) {
    int done = 1;
    for (int i = 0; i < n; i++) {
      void *samples[1] = { NULL }; dds_sample_info_t info[1];
      int r = dds_take(readers[i], samples, info, 1, 1);
      if (r > 0 && info[0].valid_data && kinds[i] == 4) {
        const dds_builtintopic_endpoint_t *e = samples[0];
        if (!strncmp(e->topic_name, prefixes[i], strlen(prefixes[i]))) {
          got[i]++;
          printf("writer %d %d", i, got[i]);
          print_hex(e->key.v, 16);
          print_hex(e->participant_key.v, 16);
          printf(" %s %s", e->topic_name, e->type_name);
          print_user_data(e->qos);
          printf("\n");
        }
      } else if (r > 0 && info[0].valid_data && kinds[i] == 3) {
        const rmw_dds_common_msg_dds__ParticipantEntitiesInfo_ *m = samples[0];
        got[i]++;
        printf("entities %d %d", i, got[i]);
        print_hex(m->gid.data, 16);
        for (uint32_t k = 0; k < m->node_entities_info_seq._length; k++) {
          const rmw_dds_common_msg_dds__NodeEntitiesInfo_ *node = &m->node_entities_info_seq._buffer[k];
          printf(" node %s %s %u", node->node_namespace, node->node_name, node->writer_gid_seq._length);
          for (uint32_t w = 0; w < node->writer_gid_seq._length; w++)
            print_hex(node->writer_gid_seq._buffer[w].data, 16);
        }
        printf("\n");
      } else if (r > 0 && info[0].valid_data) {
        got[i]++;
        double t = now_s() - t0;
        if (kinds[i] == 0) {
          const nav_msgs_msg_dds__OccupancyGrid_ *m = samples[0];
          char path[1024]; snprintf(path, sizeof path, "%s/%d.%d.bin", outdir, i, got[i]);
          FILE *f = fopen(path, "wb");
          if (!f || fwrite(m->data._buffer, 1, m->data._length, f) != m->data._length) { perror(path); return 1; }
          fclose(f);
          printf("grid %d %d %d %u %s %d %u %.9g %u %u", i, got[i], m->header.stamp.sec, m->header.stamp.nanosec,
                 m->header.frame_id, m->info.map_load_time.sec, m->info.map_load_time.nanosec,
                 (double)m->info.resolution, m->info.width, m->info.height);
          print_pose(&m->info.origin);
          printf(" %u t=%.6f\n", m->data._length, t);
        } else if (kinds[i] == 1) {
          const geometry_msgs_msg_dds__PoseArray_ *m = samples[0];
          printf("poses %d %d %d %u %s %u", i, got[i], m->header.stamp.sec, m->header.stamp.nanosec,
                 m->header.frame_id, m->poses._length);
          for (uint32_t k = 0; k < m->poses._length; k++) print_pose(&m->poses._buffer[k]);
          printf(" t=%.6f\n", t);
        } else {
          const nav2_msgs_msg_dds__CostmapFilterInfo_ *m = samples[0];
          printf("info %d %d %d %u %s %u %s %.9g %.9g t=%.6f\n", i, got[i], m->header.stamp.sec,
                 m->header.stamp.nanosec, m->header.frame_id, (unsigned)m->type, m->filter_mask_topic,
                 (double)m->base, (double)m->multiplier, t);
        }
        fflush(stdout);
      }
      if (r > 0) dds_return_loan(readers[i], samples, r);
      if (got[i] < want[i]) done = 0;
    }
    for (int r = 1; participants > 0 && r > 0;) {  /* every participant seen so far */
      void *ps[1] = { NULL }; dds_sample_info_t pi[1];
      r = dds_take(participants, ps, pi, 1, 1);
      if (r > 0 && pi[0].valid_data) {
        const dds_builtintopic_participant_t *p = ps[0];
        printf("participant");
        print_hex(p->key.v, 16);
        print_user_data(p->qos);
        printf("\n");
        fflush(stdout);
      }
      if (r > 0) dds_return_loan(participants, ps, r);
    }
    if (done) break;
    if (now_s() - t0 > timeout) { fprintf(stderr, "timeout\n"); return 2; }
    dds_sleepfor(DDS_MSECS(2));
  }
  printf("DONE\n"); fflush(stdout);
  dds_delete(dp);
  return 0;
}
