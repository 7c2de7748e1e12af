// SPDX-License-Identifier: Apache-2.0
// A DDS reader for the tests of toonforce-dds (tests/dds/dds_bridge_test.py): what a ROS 2
// node on another host would see. It joins the domain, lists every publication discovered whose
// topic starts with rt/toonforce/ (topic and type name as they travel in discovery, with the
// writer's reliability), and prints each sample of one device's pose, twist, wrench and faults:
//
//   toonforce_dds_echo --domain D --device NAME --samples N [--timeout S] [--until-gone yes] [--send TEXT ...]
//
// With --until-gone, once it has its poses it waits until the pose's writer is no longer alive
// (its liveliness lapsed, or it was deleted) and prints gone,SECONDS_SINCE_THE_LAST_POSE.
// With --send, it also writes each TEXT on rt/toonforce/control (reliable) once a reader of it
// is there, in order, and prints each reply on rt/toonforce/control_reply: reply,TEXT.
//
// One CSV line per item: publication,TOPIC,TYPE,best_effort|reliable ;
// pose,X,Y,Z,QW,FRAME_ID,STAMP_S ; twist,VX,VY,VZ ; wrench,FX,FY,FZ ; faults,BITS.
// Exits 0 after N poses, 1 if they did not come within the timeout.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "dds/dds.h"
#include "ros2_msgs.h"

namespace {

dds_entity_t reader(dds_entity_t participant, const dds_topic_descriptor_t* type, const std::string& name) {
  const dds_entity_t topic = dds_create_topic(participant, type, name.c_str(), nullptr, nullptr);
  dds_qos_t* qos = dds_create_qos();
  dds_qset_reliability(qos, DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 1000);
  const dds_entity_t r = dds_create_reader(participant, topic, qos, nullptr);
  dds_delete_qos(qos);
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  unsigned domain = 0;
  std::string device = "device";
  long wanted = 10;
  double timeout_s = 20.0;
  std::vector<std::string> sends;
  bool until_gone = false;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--send") sends.emplace_back(argv[i + 1]);
    if (flag == "--until-gone") until_gone = std::string(argv[i + 1]) == "yes";
    if (flag == "--domain") domain = static_cast<unsigned>(std::strtoul(argv[i + 1], nullptr, 10));
    if (flag == "--device") device = argv[i + 1];
    if (flag == "--samples") wanted = std::strtol(argv[i + 1], nullptr, 10);
    if (flag == "--timeout") timeout_s = std::strtod(argv[i + 1], nullptr);
  }
  const dds_entity_t participant = dds_create_participant(domain, nullptr, nullptr);
  if (participant < 0) {
    std::fprintf(stderr, "dds_echo: cannot join domain %u: %s\n", domain, dds_strretcode(participant));
    return 2;
  }
  const std::string base = "rt/toonforce/" + device + "/";
  const dds_entity_t pose = reader(participant, &geometry_msgs_msg_dds__PoseStamped__desc, base + "pose");
  const dds_entity_t twist = reader(participant, &geometry_msgs_msg_dds__TwistStamped__desc, base + "twist");
  const dds_entity_t wrench = reader(participant, &geometry_msgs_msg_dds__WrenchStamped__desc, base + "wrench");
  const dds_entity_t faults = reader(participant, &std_msgs_msg_dds__UInt32__desc, base + "faults");
  const dds_entity_t publications = dds_create_reader(participant, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, nullptr, nullptr);
  dds_entity_t control = 0;
  dds_entity_t replies = 0;
  if (!sends.empty()) {
    dds_qos_t* qos = dds_create_qos();
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 64);
    control = dds_create_writer(
        participant,
        dds_create_topic(participant, &std_msgs_msg_dds__String__desc, "rt/toonforce/control", nullptr, nullptr), qos,
        nullptr);
    replies = dds_create_reader(
        participant,
        dds_create_topic(participant, &std_msgs_msg_dds__String__desc, "rt/toonforce/control_reply", nullptr, nullptr),
        qos, nullptr);
    dds_delete_qos(qos);
  }
  std::size_t sent = 0;
  std::size_t replied = 0;
  std::set<std::string> listed;
  long poses = 0;
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while ((poses < wanted || replied < sends.size()) && std::chrono::steady_clock::now() < until) {
    if (sent < sends.size()) {
      dds_publication_matched_status_t matched{};
      dds_get_publication_matched_status(control, &matched);
      if (matched.current_count > 0) {  // the bridge's reader is there: it gets every message, in order
        for (; sent < sends.size(); ++sent) {
          std_msgs_msg_dds__String_ message{};
          message.data = sends[sent].data();
          dds_write(control, &message);
        }
      }
    }
    void* samples[16] = {};
    dds_sample_info_t infos[16];
    int n = dds_take(publications, samples, infos, 16, 16);
    for (int i = 0; i < n; ++i) {
      if (!infos[i].valid_data) continue;
      const auto* e = static_cast<const dds_builtintopic_endpoint_t*>(samples[i]);
      const std::string topic = e->topic_name != nullptr ? e->topic_name : "";
      if (topic.rfind("rt/toonforce/", 0) != 0 || !listed.insert(topic).second) continue;
      dds_reliability_kind_t kind = DDS_RELIABILITY_BEST_EFFORT;
      dds_duration_t blocking = 0;
      dds_qget_reliability(e->qos, &kind, &blocking);
      std::printf("publication,%s,%s,%s\n", topic.c_str(), e->type_name != nullptr ? e->type_name : "",
                  kind == DDS_RELIABILITY_RELIABLE ? "reliable" : "best_effort");
    }
    if (n > 0) dds_return_loan(publications, samples, n);
    // Loaned samples (the reader's own memory, strings included), given back after printing.
    const auto each = [](dds_entity_t r, auto&& print) {
      void* loaned[16] = {};
      dds_sample_info_t info[16];
      const int got = dds_take(r, loaned, info, 16, 16);
      for (int i = 0; i < got; ++i) {
        if (info[i].valid_data) print(loaned[i]);
      }
      if (got > 0) dds_return_loan(r, loaned, got);
    };
    each(pose, [&](void* s) {
      const auto* p = static_cast<const geometry_msgs_msg_dds__PoseStamped_*>(s);
      std::printf("pose,%.17g,%.17g,%.17g,%.17g,%s,%.9f\n", p->pose.position.x, p->pose.position.y, p->pose.position.z,
                  p->pose.orientation.w, p->header.frame_id != nullptr ? p->header.frame_id : "",
                  static_cast<double>(p->header.stamp.sec) + 1e-9 * static_cast<double>(p->header.stamp.nanosec));
      ++poses;
    });
    each(twist, [](void* s) {
      const auto* t = static_cast<const geometry_msgs_msg_dds__TwistStamped_*>(s);
      std::printf("twist,%.17g,%.17g,%.17g\n", t->twist.linear.x, t->twist.linear.y, t->twist.linear.z);
    });
    each(wrench, [](void* s) {
      const auto* w = static_cast<const geometry_msgs_msg_dds__WrenchStamped_*>(s);
      std::printf("wrench,%.17g,%.17g,%.17g\n", w->wrench.force.x, w->wrench.force.y, w->wrench.force.z);
    });
    if (replies != 0) {
      each(replies, [&](void* s) {
        const char* data = static_cast<const std_msgs_msg_dds__String_*>(s)->data;
        std::printf("reply,%s\n", data != nullptr ? data : "");
        ++replied;
      });
    }
    each(faults, [](void* s) { std::printf("faults,%u\n", static_cast<const std_msgs_msg_dds__UInt32_*>(s)->data); });
    std::fflush(stdout);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  bool gone = false;
  if (until_gone && poses >= wanted) {
    const auto last_pose = std::chrono::steady_clock::now();
    while (!gone && std::chrono::steady_clock::now() < until) {
      dds_liveliness_changed_status_t alive{};
      dds_get_liveliness_changed_status(pose, &alive);
      if (alive.alive_count == 0) {
        gone = true;
        std::printf("gone,%.3f\n", std::chrono::duration<double>(std::chrono::steady_clock::now() - last_pose).count());
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }
  dds_delete(participant);
  return poses >= wanted && replied >= sends.size() && (!until_gone || gone) ? 0 : 1;
}
