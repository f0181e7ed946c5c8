// A ROS 2 subscription as rmw_fastrtps makes it, in C++ on Fast DDS (types from fastddsgen).
//
// usage: fastdds_reader DOMAIN OUTDIR TIMEOUT_S KIND:DDS_TOPIC:COUNT...
// Same arguments and output lines as cyclone_reader.c. QoS as rmw_fastrtps maps a ROS 2
// subscription to nav2's /map: reliable, transient-local, keep-last 1, XCDR1, history memory
// PREALLOCATED_WITH_REALLOC (rmw_fastrtps' choice; samples larger than the type's bound fit).
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include "ros2_msgs.h"
#include "ros2_msgsPubSubTypes.h"

using namespace eprosima::fastdds::dds;
using Clock = std::chrono::steady_clock;
namespace nav = nav_msgs::msg::dds_;
namespace geo = geometry_msgs::msg::dds_;
namespace nav2 = nav2_msgs::msg::dds_;

static Clock::time_point t0;
static double elapsed() { return std::chrono::duration<double>(Clock::now() - t0).count(); }

static void print_pose(const geo::Pose_ &p) {
  std::printf(" %.17g %.17g %.17g %.17g %.17g %.17g %.17g", p.position().x(), p.position().y(),
              p.position().z(), p.orientation().x(), p.orientation().y(), p.orientation().z(),
              p.orientation().w());
}

int main(int argc, char **argv) {
  t0 = Clock::now();
  if (argc < 5) {
    std::fprintf(stderr, "usage: %s DOMAIN OUTDIR TIMEOUT_S KIND:TOPIC:COUNT...\n", argv[0]);
    return 1;
  }
  int domain = std::atoi(argv[1]);
  std::string outdir = argv[2];
  double timeout = std::atof(argv[3]);
  DomainParticipant *dp = DomainParticipantFactory::get_instance()->create_participant(
      domain, PARTICIPANT_QOS_DEFAULT);
  if (!dp) { std::fprintf(stderr, "cannot create participant\n"); return 1; }
  TypeSupport grid_t(new nav::OccupancyGrid_PubSubType());
  TypeSupport poses_t(new geo::PoseArray_PubSubType());
  TypeSupport info_t(new nav2::CostmapFilterInfo_PubSubType());
  grid_t.register_type(dp);
  poses_t.register_type(dp);
  info_t.register_type(dp);
  Subscriber *sub = dp->create_subscriber(SUBSCRIBER_QOS_DEFAULT);
  DataReaderQos rq = DATAREADER_QOS_DEFAULT;
  rq.reliability().kind = RELIABLE_RELIABILITY_QOS;
  rq.durability().kind = TRANSIENT_LOCAL_DURABILITY_QOS;
  rq.history().kind = KEEP_LAST_HISTORY_QOS;
  rq.history().depth = 1;
  rq.endpoint().history_memory_policy =
      eprosima::fastrtps::rtps::PREALLOCATED_WITH_REALLOC_MEMORY_MODE;
  rq.type_consistency().representation.m_value.clear();
  rq.type_consistency().representation.m_value.push_back(XCDR_DATA_REPRESENTATION);

  int n = argc - 4;
  std::vector<DataReader *> readers;
  std::vector<int> kinds, want, got(n, 0);
  for (int i = 0; i < n; i++) {
    std::string spec = argv[4 + i];
    size_t a = spec.find(':'), b = spec.rfind(':');
    if (a == std::string::npos || a == b) { std::fprintf(stderr, "bad spec %s\n", spec.c_str()); return 1; }
    std::string kind = spec.substr(0, a), topic = spec.substr(a + 1, b - a - 1);
    want.push_back(std::atoi(spec.substr(b + 1).c_str()));
    std::string type;
    if (kind == "grid") { kinds.push_back(0); type = grid_t.get_type_name(); }
    else if (kind == "poses") { kinds.push_back(1); type = poses_t.get_type_name(); }
    else if (kind == "info") { kinds.push_back(2); type = info_t.get_type_name(); }
    else { std::fprintf(stderr, "bad kind %s\n", kind.c_str()); return 1; }
    Topic *tp = dp->create_topic(topic, type, TOPIC_QOS_DEFAULT);
    DataReader *r = tp ? sub->create_datareader(tp, rq) : nullptr;
    if (!r) { std::fprintf(stderr, "cannot create reader on %s\n", topic.c_str()); return 1; }
    readers.push_back(r);
  }
  std::printf("READY\n");
  std::fflush(stdout);
  for (;;) {
    bool done = true;
    for (int i = 0; i < n; i++) {
      SampleInfo info;
      if (kinds[i] == 0) {
        nav::OccupancyGrid_ m;
        if (readers[i]->take_next_sample(&m, &info) == ReturnCode_t::RETCODE_OK && info.valid_data) {
          got[i]++;
          double t = elapsed();
          std::string path = outdir + "/" + std::to_string(i) + "." + std::to_string(got[i]) + ".bin";
          FILE *f = std::fopen(path.c_str(), "wb");
          if (!f || std::fwrite(m.data().data(), 1, m.data().size(), f) != m.data().size()) {
            std::perror(path.c_str());
            return 1;
          }
          std::fclose(f);
          const auto &h = m.header();
          const auto &mi = m.info();
          std::printf("grid %d %d %d %u %s %d %u %.9g %u %u", i, got[i], h.stamp().sec(),
                      h.stamp().nanosec(), h.frame_id().c_str(), mi.map_load_time().sec(),
                      mi.map_load_time().nanosec(), (double)mi.resolution(), mi.width(), mi.height());
          print_pose(mi.origin());
          std::printf(" %zu t=%.6f\n", m.data().size(), t);
        }
      } else if (kinds[i] == 1) {
        geo::PoseArray_ m;
        if (readers[i]->take_next_sample(&m, &info) == ReturnCode_t::RETCODE_OK && info.valid_data) {
          got[i]++;
          const auto &h = m.header();
          std::printf("poses %d %d %d %u %s %zu", i, got[i], h.stamp().sec(), h.stamp().nanosec(),
                      h.frame_id().c_str(), m.poses().size());
          for (const auto &p : m.poses()) print_pose(p);
          std::printf(" t=%.6f\n", elapsed());
        }
      } else {
        nav2::CostmapFilterInfo_ m;
        if (readers[i]->take_next_sample(&m, &info) == ReturnCode_t::RETCODE_OK && info.valid_data) {
          got[i]++;
          const auto &h = m.header();
          std::printf("info %d %d %d %u %s %u %s %.9g %.9g t=%.6f\n", i, got[i], h.stamp().sec(),
                      h.stamp().nanosec(), h.frame_id().c_str(), (unsigned)m.type(),
                      m.filter_mask_topic().c_str(), (double)m.base(), (double)m.multiplier(),
                      elapsed());
        }
      }
      std::fflush(stdout);
      if (got[i] < want[i]) done = false;
    }
    if (done) break;
    if (elapsed() > timeout) { std::fprintf(stderr, "timeout\n"); return 2; }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  std::printf("DONE\n");
  std::fflush(stdout);
  dp->delete_contained_entities();
  DomainParticipantFactory::get_instance()->delete_participant(dp);
  return 0;
}
