// Table-driven bad input for the config: NaN and ±inf for EVERY floating-point key the readers
// know (taken from the readers' own key catalog, so a new key is covered without a new test),
// every path key given a directory, a FIFO, a device and a missing folder, duplicate and
// non-scalar keys. Each case must be refused with a message naming the key — and never block
// (a FIFO is only stat()ed, never opened).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include "sempose/config/app_config.hpp"
#include "sempose/config/reader.hpp"
#include "sempose/config/target_name.hpp"

namespace sempose::config {
namespace {

const std::string kPattern = std::string(SEMPOSE_TEST_DATA) + "/sem/needle_contact_eb.pgm";

// A config that uses every section and one item of every list, so every key is reachable.
std::string base_yaml(const std::string& dir) {
  return "source: sim\n"
         "scan: {field_w: 640, field_h: 480}\n"
         "sim:\n"
         "  clock: virtual\n"
         "  drift: [{amplitude_px: 0.4, period_s: 23, direction_deg: 10, phase_deg: 0}]\n"
         "  background: {source: procedural, mean: 0.3, contrast: 0.5, grain_px: 3}\n"
         "  targets:\n"
         "    - {enabled: true, texture: {source: lamella}, size: [100, 64], brightness: 0.9, start: [320, 240, 0],\n"
         "       trajectory: {kind: sine, amplitude_x_px: 20, amplitude_y_px: 10, amplitude_phi_deg: 5, period_s: 4}}\n"
         "replay: {frames_dir: " + dir + ", loop: false}\n"
         "targets:\n"
         "  - name: t0\n"
         "    pattern_sets: [{file: " + kPattern + ", nm_per_px: 40, mask: " + kPattern + "}]\n"
         "tracker: {filter: {enabled: false}}\n"
         "governor: {margin: 0.2}\n"
         "pipeline: {schedule: [0]}\n"
         "output: {poses_csv: " + dir + "/poses.csv, hist_dir: " + dir + "/hist}\n"
         "can: {log_file: " + dir + "/can.log}\n"
         "gpio: {chip: '', pose_valid_line: -1}\n";
}

std::string temp_dir() {
  const std::string d = ::testing::TempDir() + "config_faults_" + std::to_string(::getpid());
  std::filesystem::create_directories(d);
  return d;
}

// Sets the scalar at a dotted path with [i] indices (a.b[0].c) in a YAML tree.
void set_path(YAML::Node root, const std::string& path, const std::string& value) {
  std::vector<std::string> parts;
  std::size_t a = 0;
  while (a <= path.size()) {
    const std::size_t b = std::min(path.find('.', a), path.size());
    parts.push_back(path.substr(a, b - a));
    a = b + 1;
  }
  YAML::Node node = root;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    std::string key = parts[i];
    int index = -1;
    if (const auto lb = key.find('['); lb != std::string::npos) {
      index = std::stoi(key.substr(lb + 1));
      key = key.substr(0, lb);
    }
    YAML::Node child = node[key];
    // Node::operator= assigns content into the referenced node: rebind with reset().
    if (index >= 0) child.reset(YAML::Node(child[static_cast<std::size_t>(index)]));
    if (i + 1 == parts.size()) {
      child = YAML::Load(value);
      return;
    }
    node.reset(child);
  }
}

std::string with(const std::string& base, const std::string& path, const std::string& value) {
  YAML::Node root = YAML::Load(base);
  set_path(root, path, value);
  YAML::Emitter out;
  out << root;
  return out.c_str();
}

TEST(ConfigFaults, BaseConfigIsValid) {
  const std::string dir = temp_dir();
  AppConfig c;
  std::string e;
  EXPECT_TRUE(parse_app_config(base_yaml(dir), dir + "/c.yaml", c, e)) << e;
}

TEST(ConfigFaults, NanAndInfinityAreRefusedForEveryFloatKey) {
  const std::string dir = temp_dir();
  const std::string base = base_yaml(dir);
  int float_keys = 0;
  for (const KeyInfo& k : config_keys(base)) {
    if (k.kind != KeyKind::kFloat) continue;
    ++float_keys;
    // YAML's own spellings (refused as not finite) and C's (refused as not numbers).
    for (const char* v : {".nan", ".NaN", ".inf", "-.inf", "+.Inf", "NaN", "inf", "-nan"}) {
      AppConfig c;
      std::string e;
      const std::string text = with(base, k.path, v);
      EXPECT_FALSE(parse_app_config(text, dir + "/c.yaml", c, e)) << k.path << " = " << v << " was accepted";
      EXPECT_NE(e.find(k.path + ": '" + v + "' is not a"), std::string::npos)
          << k.path << " = " << v << ":\n" << e;
    }
  }
  std::printf("NaN/inf refused for %d floating-point keys\n", float_keys);
  EXPECT_GE(float_keys, 60) << "the catalog lost keys (every section and list item is in the base config)";
}

TEST(ConfigFaults, HugeAndFractionalIntegersAreRefused) {
  const std::string dir = temp_dir();
  const std::string base = base_yaml(dir);
  int int_keys = 0;
  for (const KeyInfo& k : config_keys(base)) {
    if (k.kind != KeyKind::kInteger) continue;
    ++int_keys;
    for (const char* v : {"1e300", "-1e300", "0.5", ".nan"}) {
      AppConfig c;
      std::string e;
      EXPECT_FALSE(parse_app_config(with(base, k.path, v), dir + "/c.yaml", c, e)) << k.path << " = " << v;
      EXPECT_NE(e.find(k.path + ":"), std::string::npos) << k.path << " = " << v << ":\n" << e;
    }
  }
  std::printf("overflowing/fractional values refused for %d integer keys\n", int_keys);
  EXPECT_GE(int_keys, 20);
}

struct PathCase {
  const char* key;
  bool output;     // an output file (device allowed: /dev/null, /dev/full)
  bool directory;  // the key names a directory
};

TEST(ConfigFaults, PathKeysAreCheckedForTheirKindBeforeAnyOpen) {
  const std::string dir = temp_dir();
  const std::string fifo = dir + "/fifo";
  ::unlink(fifo.c_str());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string a_file = dir + "/plain.txt";
  std::ofstream(a_file) << "x";
  const std::string base = base_yaml(dir);
  const PathCase cases[] = {
      {"targets[0].pattern_sets[0].file", false, false}, {"targets[0].pattern_sets[0].mask", false, false},
      {"replay.frames_dir", false, true},                {"output.poses_csv", true, false},
      {"can.log_file", true, false},                     {"output.hist_dir", true, true},
  };
  struct Kind {
    const char* what;
    std::string path;
  };
  const Kind kinds[] = {{"directory", dir},
                        {"FIFO", fifo},
                        {"character device", "/dev/zero"},
                        {"missing folder", dir + "/no/such/folder/f"},
                        {"below a regular file", a_file + "/f"}};
  int refused = 0;
  for (const PathCase& pc : cases) {
    for (const Kind& k : kinds) {
      // What is fine: a directory for a directory key; a device for an output file
      // (/dev/null discards); a missing folder for an output (sempose creates it).
      const std::string kind = k.what;
      const bool ok = (kind == "directory" && pc.directory) || (kind == "character device" && pc.output && !pc.directory) ||
                      (kind == "missing folder" && pc.output);
      std::string text = with(base, pc.key, "'" + k.path + "'");
      if (std::string(pc.key) == "replay.frames_dir") text = with(text, "source", "replay");
      AppConfig c;
      std::string e;
      const bool accepted = parse_app_config(text, dir + "/c.yaml", c, e);
      if (ok) {
        EXPECT_TRUE(accepted) << pc.key << " = " << k.what << ":\n" << e;
      } else {
        ++refused;
        EXPECT_FALSE(accepted) << pc.key << " = " << k.what << " was accepted";
        EXPECT_NE(e.find(pc.key), std::string::npos) << pc.key << " = " << k.what << ":\n" << e;
        EXPECT_NE(e.find(k.path), std::string::npos) << "the message names the path:\n" << e;
      }
    }
  }
  std::printf("%d bad path cases refused by name (6 keys x directory/FIFO/device/missing folder/below a file)\n",
              refused);
  ::unlink(fifo.c_str());
}

TEST(ConfigFaults, ConfigFileItselfMustBeARegularFile) {
  const std::string dir = temp_dir();
  const std::string fifo = dir + "/config_fifo";
  ::unlink(fifo.c_str());
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  for (const std::string& p : {dir, fifo, std::string("/dev/zero"), dir + "/missing/c.yaml"}) {
    AppConfig c;
    std::string e;
    EXPECT_FALSE(load_app_config(p, c, e)) << p;
    EXPECT_NE(e.find(p + ": cannot read the config: it is "), std::string::npos) << e;
  }
  ::unlink(fifo.c_str());
}

// A 4 MB config (a 2,000,000-entry pipeline.schedule) was parsed whole before the list's limit
// refused it: 6.9 s and 945 MB (hostile round 12). A config beyond 1 MiB is refused unparsed.
TEST(ConfigFaults, AConfigBeyondOneMebibyteIsRefusedUnparsed) {
  const std::string path = temp_dir() + "/huge.yaml";
  {
    std::ofstream out(path);
    out << "pipeline:\n  schedule: [";
    for (int i = 0; i < 600000; ++i) out << "0, ";
    out << "0]\n";
  }
  AppConfig c;
  std::string e;
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_FALSE(load_app_config(path, c, e));
  EXPECT_NE(e.find(path + ": the config is larger than 1 MiB"), std::string::npos) << e.substr(0, 300);
  std::printf("refused in %.3f s\n", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
}

TEST(ConfigFaults, DuplicateAndNonScalarKeysAreErrors) {
  AppConfig c;
  std::string e;
  EXPECT_FALSE(parse_app_config("tracker:\n  score_threshold: 0.3\n  score_threshold: 0.9\n", "d.yaml", c, e));
  EXPECT_NE(e.find("d.yaml:3:3: tracker.score_threshold: duplicate key (first given on line 2)"), std::string::npos)
      << e;
  EXPECT_FALSE(parse_app_config("tracker:\n  ? [a, b]\n  : 1\n", "n.yaml", c, e));
  EXPECT_NE(e.find("tracker: a key must be a plain name"), std::string::npos) << e;
  EXPECT_FALSE(parse_app_config("? {x: 1}\n: 2\n", "n.yaml", c, e));
  EXPECT_NE(e.find("a key must be a plain name"), std::string::npos) << e;
}

// An output named like a folder ("x.csv/") passed while nothing of that name existed and failed
// at open, after the work (found probing: pattern --out p.pgm/ once the frames were averaged).
TEST(ConfigFaults, AnOutputEndingInASlashIsRefusedBeforeAnyWork) {
  const std::string dir = temp_dir();
  EXPECT_NE(output_path_problem(dir + "/x.csv/").find("a folder's name, ending in '/'"), std::string::npos);
  EXPECT_EQ(output_path_problem(dir + "/x.csv"), "");
  AppConfig c;
  std::string e;
  EXPECT_FALSE(parse_app_config(with(base_yaml(dir), "output.poses_csv", dir + "/p.csv/"), "o.yaml", c, e));
  EXPECT_NE(e.find("output.poses_csv: '" + dir + "/p.csv/' cannot be written: it is a folder's name"), std::string::npos) << e;
}

// A 10 MB value came back as a 10 MB error line (found probing): each message is cut, saying so.
TEST(ConfigFaults, AnErrorAboutAHugeValueIsCut) {
  AppConfig c;
  std::string e;
  EXPECT_FALSE(parse_app_config("sim:\n  clock: " + std::string(100000, 'x') + "\n", "h.yaml", c, e));
  EXPECT_NE(e.find("h.yaml:2:10: sim.clock: 'xxx"), std::string::npos) << e.substr(0, 200);
  EXPECT_NE(e.find(" bytes left out) ... "), std::string::npos) << e.substr(0, 200);
  EXPECT_LT(e.size(), 1200u);
}

// A long, legal path (1.4 kB) lost the reason at the end of its error when the end was cut:
// "(596 more bytes)" instead of what is wrong with it (hostile round 12). The middle is cut.
TEST(ConfigFaults, AnErrorAboutALongPathKeepsItsReason) {
  std::string path = "/nonexistent";
  for (int i = 0; i < 7; ++i) path += "/" + std::string(200, 'd');
  AppConfig c;
  std::string e;
  EXPECT_FALSE(parse_app_config("sim:\n  background: {source: image, path: \"" + path + ".pgm\"}\n", "p.yaml", c, e));
  EXPECT_NE(e.find("p.yaml:2:"), std::string::npos) << e.substr(0, 200);
  EXPECT_NE(e.find(" bytes left out) ... "), std::string::npos) << e.substr(0, 200);
  EXPECT_LT(e.size(), 1200u);
  // The full message's end survives (the reason after the path), whatever its wording.
  std::string full;
  ASSERT_FALSE(parse_app_config("sim:\n  background: {source: image, path: \"/nonexistent/x.pgm\"}\n", "p.yaml", c, full));
  const std::string reason = full.substr(full.find("x.pgm") + 5);
  ASSERT_FALSE(reason.empty()) << full;
  EXPECT_NE(e.find(reason.substr(0, reason.find('\n'))), std::string::npos) << e << "\n--- short: " << full;
}

// Values read and then not used, each accepted without a word (found probing): an empty start,
// size or crop kept the default; a crop of no width cropped nothing; `value` beside from / to of
// a profile lost to them; a path beside a procedural texture was never opened; an empty target
// item added the default target.
TEST(ConfigFaults, SimValuesThatWouldBeIgnoredAreNamed) {
  const std::string dir = temp_dir(), base = base_yaml(dir);
  const std::pair<std::string, std::string> cases[][2] = {
      {{"sim.targets[0].start", "[]"}, {"sim.targets[0].start", "expected [x_px, y_px, phi_deg]"}},
      {{"sim.targets[0].size", "[]"}, {"sim.targets[0].size", "expected [width_px, height_px]"}},
      {{"sim.targets[0].scale", "{value: 1, from: 0.5, to: 2}"}, {"sim.targets[0].scale.value", "exclude each other"}},
      {{"sim.targets[0].texture", "{source: lamella, path: /nonexistent.pgm}"},
       {"sim.targets[0].texture.path", "applies to texture source 'image' only, not 'lamella'"}},
      {{"sim.targets[0].texture", "{source: image, path: " + kPattern + ", crop: [0, 0, 0, 50]}"},
       {"sim.targets[0].texture.crop", "w and h must be at least 1"}},
      {{"sim.targets[0].texture", "{source: image, path: " + kPattern + ", crop: []}"},
       {"sim.targets[0].texture.crop", "expected [x, y, w, h] (4 numbers), got 0"}},
      {{"sim.targets[0]", "~"}, {"sim.targets", "item 0 is empty"}},
      // Twelfth round: a trajectory key its kind does not read (no kind: a still target), a
      // mask on a procedural texture, a procedural background's settings on an image.
      {{"sim.targets[0].trajectory", "{vx_px_s: 100}"},
       {"sim.targets[0].trajectory.vx_px_s", "applies to kind linear only, not 'static' (no kind given: the target's default)"}},
      {{"sim.targets[0].trajectory", "{kind: sine, vx_px_s: 100}"},
       {"sim.targets[0].trajectory.vx_px_s", "applies to kind linear only, not 'sine'"}},
      {{"sim.targets[0].trajectory", "{kind: spin, omega_deg_s: 30, period_s: 2}"},
       {"sim.targets[0].trajectory.period_s", "applies to kind sine, steps, jumps only, not 'spin'"}},
      {{"sim.targets[0].texture", "{source: lamella, mask: threshold_all, mask_level: 0.1}"},
       {"sim.targets[0].texture.mask", "applies to texture source 'image' only, not 'lamella'"}},
      {{"sim.background", "{source: image, path: " + kPattern + ", grain_px: 30}"},
       {"sim.background.grain_px", "applies to background source 'procedural' only, not 'image'"}},
      {{"sim.background", "{mean: 0.3, crop: [0, 0, 10, 10]}"},
       {"sim.background.crop", "applies to background source 'image' only, not 'procedural'"}},
      // Thirteenth round: a change's shape beside a constant (the frames were those without it).
      {{"sim.targets[0].scale", "{value: 1.2, start_s: 5}"},
       {"sim.targets[0].scale.start_s", "shapes a change from -> to; value is a constant"}},
      {{"sim.targets[0].scale", "{from: 1.2, ramp_s: 3}"},
       {"sim.targets[0].scale.ramp_s", "shapes a change from -> to; from without to is a constant"}},
      // A margin that pins the target (a "moving" recording that is a still one).
      {{"sim.targets[0].trajectory", "{kind: random_walk, margin_px: 240}"},
       {"sim.targets[0].trajectory.margin_px", "240 px leaves the target no room to move in the 640x480 field (below 239.5"}},
  };
  for (const auto& c : cases) {
    AppConfig cfg;
    std::string e;
    EXPECT_FALSE(parse_app_config(with(base, c[0].first, c[0].second), "s.yaml", cfg, e)) << c[0].first << ": " << c[0].second;
    EXPECT_NE(e.find(c[1].first + ": "), std::string::npos) << e;
    EXPECT_NE(e.find(c[1].second), std::string::npos) << e;
  }
  {  // A margin with room, and the default margin on a small field, are no error.
    AppConfig ok;
    std::string e2;
    EXPECT_TRUE(parse_app_config(with(base, "sim.targets[0].trajectory", "{kind: random_walk, margin_px: 230}"), "s.yaml", ok, e2))
        << e2;
  }
  // A kind that is refused is named once: its keys are not also judged against the default.
  AppConfig cfg;
  std::string e;
  EXPECT_FALSE(parse_app_config(with(base, "sim.targets[0].trajectory", "{kind: sinus, amplitude_x_px: 10}"), "s.yaml", cfg, e));
  EXPECT_NE(e.find("sim.targets[0].trajectory.kind: "), std::string::npos) << e;
  EXPECT_EQ(e.find("applies to kind"), std::string::npos) << e;
}

// A second YAML document (`---`, two configs concatenated) was dropped without a word: the
// first one ran. Refused naming its line; an empty trailing document is harmless.
TEST(ConfigFaults, ASecondYamlDocumentIsRefused) {
  AppConfig c;
  std::string e;
  EXPECT_FALSE(parse_app_config("tracker: {score_threshold: 0.3}\n---\ntracker: {score_threshold: 0.9}\n", "m.yaml", c, e));
  EXPECT_NE(e.find("m.yaml:3:1: (document 2): a second YAML document"), std::string::npos) << e;
  EXPECT_FALSE(parse_app_config("---\nscan: {field_w: 640}\n...\n--- {scan: {field_w: 320}}\n", "m.yaml", c, e));
  EXPECT_NE(e.find("a second YAML document"), std::string::npos) << e;
  EXPECT_TRUE(parse_app_config("---\ntracker: {score_threshold: 0.3}\n---\n", "m.yaml", c, e)) << e;
  EXPECT_DOUBLE_EQ(c.tracker.score_threshold, 0.3);
}

// A tag was dropped and the text read as it stands: `!!binary aGVsbG8=` named a file
// "aGVsbG8=", `!local 3` read 3. Refused naming key and tag; the core scalar tags still read.
TEST(ConfigFaults, TaggedValuesOtherThanPlainOnesAreRefused) {
  AppConfig c;
  std::string e;
  EXPECT_FALSE(parse_app_config("output: {poses_csv: !!binary aGVsbG8=}\n", "t.yaml", c, e));
  EXPECT_NE(e.find("output.poses_csv: 'aGVsbG8=' carries the tag 'tag:yaml.org,2002:binary'"),
            std::string::npos)
      << e;
  EXPECT_FALSE(parse_app_config("tracker: {roi_size_px: !local 160}\n", "t.yaml", c, e));
  EXPECT_NE(e.find("tracker.roi_size_px: '160' carries the tag '!local'"), std::string::npos) << e;
  EXPECT_FALSE(parse_app_config("pipeline: {schedule: [0, !!timestamp 1]}\n", "t.yaml", c, e));
  EXPECT_NE(e.find("pipeline.schedule[1]"), std::string::npos) << e;
  EXPECT_TRUE(parse_app_config("tracker: {roi_size_px: !!int 160, score_threshold: !!float 0.3, circular_mask: !!bool true}\n"
                               "output: {poses_csv: !!str 12.csv}\n",
                               "t.yaml", c, e))
      << e;
  EXPECT_EQ(c.tracker.roi_size_px, 160);
  // A core tag of another kind than the key's was read as the text stands (hostile round 8:
  // `!!bool 96` as the number 96).
  const std::pair<const char*, const char*> mistagged[] = {
      {"tracker: {roi_size_px: !!bool 96}\n", "tracker.roi_size_px: '96' is tagged as a boolean (!!bool), but the key takes a number"},
      {"tracker: {score_threshold: !!str 0.3}\n", "tracker.score_threshold: '0.3' is tagged as text (!!str), but the key takes a number"},
      {"tracker: {circular_mask: !!int 1}\n", "tracker.circular_mask: '1' is tagged as a number (!!int), but the key takes true or false"},
  };
  for (const auto& [yaml, says] : mistagged) {
    e.clear();
    EXPECT_FALSE(parse_app_config(yaml, "t.yaml", c, e)) << yaml;
    EXPECT_NE(e.find(says), std::string::npos) << e;
  }
}

TEST(ConfigFaults, TrackingRoiLargerThanTheScanLimitIsRefused) {
  AppConfig c;
  std::string e;
  EXPECT_FALSE(parse_app_config("scan: {max_roi_w: 128, max_roi_h: 128}\ntracker: {roi_size_px: 192}\n", "r.yaml", c, e));
  EXPECT_NE(e.find("tracker.roi_size_px: 192 gives a 192x192 ROI, larger than scan.max_roi_w/h 128x128"),
            std::string::npos)
      << e;
  // The whole field is always allowed.
  EXPECT_TRUE(parse_app_config("scan: {field_w: 160, field_h: 160, max_roi_w: 128, max_roi_h: 128}\n"
                               "tracker: {roi_size_px: 192}\n",
                               "r.yaml", c, e))
      << e;
}

TEST(ConfigFaults, ScheduleMayNameTheSimulatorsOwnTargets) {
  AppConfig c;
  std::string e;
  const std::string two = "sim:\n  targets:\n    - {texture: {source: lamella}}\n    - {texture: {source: gripper}}\n";
  EXPECT_TRUE(parse_app_config(two + "pipeline: {schedule: [0, 1, 1]}\n", "s.yaml", c, e)) << e;
  EXPECT_FALSE(parse_app_config(two + "pipeline: {schedule: [0, 2]}\n", "s.yaml", c, e));
  EXPECT_NE(e.find("pipeline.schedule: 2 is not a target index (targets: 2"), std::string::npos) << e;
}

// The false-pose probability the state decision allows (README: States, UNCERTAIN): a clear
// error naming file, key, value and the allowed range.
TEST(ConfigFaults, MaxFalseProbabilityIsRangeChecked) {
  const std::string dir = temp_dir();
  AppConfig c;
  std::string e;
  EXPECT_TRUE(parse_app_config(with(base_yaml(dir), "tracker.max_false_probability", "0.001"), dir + "/c.yaml", c, e)) << e;
  EXPECT_DOUBLE_EQ(c.tracker.max_false_probability, 0.001);
  for (const char* bad : {"0.7", "-0.01"}) {
    e.clear();
    EXPECT_FALSE(parse_app_config(with(base_yaml(dir), "tracker.max_false_probability", bad), dir + "/c.yaml", c, e));
    EXPECT_NE(e.find("c.yaml:"), std::string::npos) << e;
    EXPECT_NE(e.find(std::string("tracker.max_false_probability: ") + bad + " is outside the allowed range [0, 0.5]"), std::string::npos) << e;
  }
}

// A control character in ANY text value (paths, names, interface names, choices): a newline in
// an output path was used as the file name (breaking every line-oriented tool and log), a NUL
// from a YAML escape cut the name short where the C library read it. Every text key of the
// catalog refuses each, naming the key, the character and its place.
TEST(ConfigFaults, ControlCharactersAreRefusedInEveryTextValue) {
  const std::string dir = temp_dir();
  const std::string base = base_yaml(dir);
  int text_keys = 0;
  for (const KeyInfo& k : config_keys(base)) {
    if (k.kind != KeyKind::kText) continue;
    ++text_keys;
    struct Bad {
      const char* yaml;
      const char* says;
    };
    for (const Bad& b : {Bad{"\"a\\nb\"", "'a\\nb' holds a newline (\\n), byte 0x0a at character 2"},
                         Bad{"\"a\\0b\"", "'a\\0b' holds a NUL byte (\\0), byte 0x00 at character 2"},
                         Bad{"\"ab\\x7f\"", "'ab\\x7f' holds a DEL (\\x7f), byte 0x7f at character 3"},
                         Bad{"\"\\x01\"", "'\\x01' holds a control character, byte 0x01 at character 1"},
                         // The Unicode ones (found probing: accepted, used as file names): YAML's own
                         // line-break escapes, a C1 control, a bidirectional override, a zero-width
                         // space; characters before them are counted whole ("é" is one).
                         Bad{"\"a\\Nb\"", "'a\\x85b' holds a byte that is not UTF-8, byte 0x85 at character 2"},
                         Bad{"\"a\\Lb\"", "'a\\u2028b' holds U+2028 (a line separator), bytes 0xe2 0x80 0xa8 at character 2"},
                         Bad{"\"\u00e9\\Pb\"", "'\u00e9\\u2029b' holds U+2029 (a paragraph separator), bytes 0xe2 0x80 0xa9 at character 2"},
                         Bad{"\"a\\x9bb\"", "'a\\u009bb' holds U+009B (a C1 control character), bytes 0xc2 0x9b at character 2"},
                         Bad{"\"a\\u202eb\"", "'a\\u202eb' holds U+202E (a bidirectional override), bytes 0xe2 0x80 0xae at character 2"},
                         Bad{"\"a\\u200b\"", "'a\\u200b' holds U+200B (a zero-width character), bytes 0xe2 0x80 0x8b at character 2"}}) {
      AppConfig c;
      std::string e;
      EXPECT_FALSE(parse_app_config(with(base, k.path, b.yaml), dir + "/c.yaml", c, e)) << k.path << " = " << b.yaml;
      EXPECT_NE(e.find(k.path + ": " + b.says), std::string::npos) << k.path << " = " << b.yaml << ":\n" << e;
    }
  }
  std::printf("control characters refused for %d text keys\n", text_keys);
  EXPECT_GE(text_keys, 15);
}

// Every error line is printable, whatever text of the file it quotes: a key's name, a value a
// number or bool key refused, and yaml-cpp's syntax messages came out raw — a terminal escape
// (retitling the window, clearing the screen), a bidirectional override, and a newline in a key
// that forged a line of its own on stderr ("summary: poses=999 ok: unknown key"; found probing).
TEST(ConfigFaults, ErrorLinesQuoteTheFilesTextEscaped) {
  const std::string dir = temp_dir();
  struct Case {
    std::string yaml;
    const char* says;  // part of the line, escaped
  };
  for (const Case& c : {Case{with(base_yaml(dir), "sim.seed", "\"1\\e]0;pwned\\a\""), "sim.seed: '1\\x1b]0;pwned\\x07' is not"},
                        Case{base_yaml(dir) + "service: {\"\\e[2J\\u202eevil\": 1}\n", "service.\\x1b[2J\\u202eevil: unknown key"},
                        Case{base_yaml(dir) + "\"a\\nsummary: poses=999 ok\": 1\n", "a\\nsummary: poses=999 ok: unknown key"},
                        Case{base_yaml(dir) + "x: \"\\\x1b\"\n", "(syntax): unknown escape character: \\x1b"},
                        // A NUL in a key was cut there: "sim: unknown key (known here: ..., sim, ...)" (hostile round 8).
                        Case{base_yaml(dir) + "\"sim\\0\": 1\n", "sim\\0: unknown key"}}) {
    AppConfig cfg;
    std::string e;
    EXPECT_FALSE(parse_app_config(c.yaml, dir + "/c.yaml", cfg, e)) << c.yaml;
    EXPECT_NE(e.find(c.says), std::string::npos) << e;
    for (const char ch : e) EXPECT_TRUE(ch == '\n' || static_cast<unsigned char>(ch) >= 0x20) << "raw control byte in:\n" << e;
    EXPECT_EQ(e.find("\u202e"), std::string::npos) << "raw bidirectional override in:\n" << e;
    // One line per error: no line of the output starts with the forged text.
    EXPECT_EQ(e.find("\nsummary:"), std::string::npos) << e;
  }
}

// A file whose lines end in CR alone (old Mac endings) is one YAML line: said as such, not only
// "the top level must be a mapping" (found probing); CRLF reads as LF does.
TEST(ConfigFaults, LinesEndedByACarriageReturnAloneAreNamed) {
  const std::string dir = temp_dir();
  std::string cr = base_yaml(dir), crlf;
  for (char& ch : cr) if (ch == '\n') ch = '\r';
  for (const char ch : base_yaml(dir)) crlf += ch == '\n' ? std::string("\r\n") : std::string(1, ch);
  AppConfig c;
  std::string e;
  EXPECT_FALSE(parse_app_config(cr, dir + "/c.yaml", c, e));
  EXPECT_NE(e.find("carriage return alone"), std::string::npos) << e;
  e.clear();
  EXPECT_TRUE(parse_app_config(crlf, dir + "/c.yaml", c, e)) << e;
}

// Three forms found probing that were read as something else: a NUL byte (the message stopped at
// it, "unknown escape character"), a quote never closed (yaml-cpp ran the value to the end of the
// file and the error quoted every line after it as that value), and `targets: []` (the simulator's
// own targets were tracked without a word); a target item that is empty or no mapping is said once.
// Quotes that close, across lines or escaped, still read.
TEST(ConfigFaults, NulUnclosedQuoteAndEmptyTargetsAreNamed) {
  const std::string dir = temp_dir();
  const std::string base = base_yaml(dir);
  struct Case {
    std::string yaml;
    const char* says;
  };
  const std::string nul = base + std::string("x: 1\0\0\n", 7);
  for (const Case& c : {Case{nul, "c.yaml:20:5: (text): a NUL byte"},
                        Case{"source: \"sim\nscan: {field_w: 1024}\n", "c.yaml:1:9: (syntax): a quote opened here is never closed"},
                        Case{"source: 'sim\nscan: {field_w: 1024}\n", "c.yaml:1:9: (syntax): a quote opened here is never closed"},
                        Case{"source: sim\ntracker:\n  subpixel: \"gaussian\n  roi_size_px: 160\n", "c.yaml:3:13: (syntax): a quote opened here is never closed"},
                        Case{"source: sim\ntargets: []\n", "c.yaml:2:10: targets: an empty list: no target to track"},
                        Case{"source: sim\ntargets: [~]\n", "c.yaml:2:10: targets: item 0 is empty"},
                        Case{"source: sim\ntargets: [p.pgm]\n", "c.yaml:2:11: targets[0]: expected a mapping of keys"}}) {
    AppConfig cfg;
    std::string e;
    EXPECT_FALSE(parse_app_config(c.yaml, dir + "/c.yaml", cfg, e)) << c.yaml;
    EXPECT_NE(e.find(c.says), std::string::npos) << e;
    // One error for one fault: a target item that is no mapping also said "needs at least one
    // pattern set", on a line of its own without a line number.
    EXPECT_EQ(e.find("needs at least one pattern set"), std::string::npos) << e;
  }
  for (const std::string& fine : {std::string("source: \"si\n  m\"\n"), std::string("source: sim\nreplay: {frames_dir: \"a\\\"b\"}\n"),
                                  std::string("source: sim\nreplay: {frames_dir: 'it''s'}\n"), std::string("source: sim # it's \"\n")}) {
    AppConfig cfg;
    std::string e;
    parse_app_config(fine, dir + "/c.yaml", cfg, e);
    EXPECT_EQ(e.find("never closed"), std::string::npos) << fine << "\n" << e;
    EXPECT_EQ(e.find("NUL"), std::string::npos) << e;
  }
}

// The review of the Unicode rule: more invisible and bidirectional characters (U+061C, U+00AD,
// U+180E, a tag character); zero-width joiners are ordinary spelling in Persian and Indic scripts
// and allowed in paths (a target name refuses them); printable() is one pass (it restarted from
// the value's start at each finding: a value of 160k tabs took 4 s, 1M minutes).
TEST(ConfigFaults, TheUnicodeRuleKnowsItsCharactersAndReadsOnce) {
  for (const char* bad : {"a\u061cb", "a\u00adb", "a\u180eb", "a\U000E0001b"})
    EXPECT_NE(sempose::config::control_character_problem(bad), "") << bad;
  EXPECT_EQ(sempose::config::control_character_problem("/data/\u0645\u06cc\u200c\u062e\u0648\u0627\u0647\u0645.csv"), "");
  EXPECT_FALSE(sempose::config::is_target_name("a\u200d"));
  EXPECT_EQ(sempose::config::printable(std::string(1 << 20, '\t')).size(), std::size_t{2} << 20);
  EXPECT_EQ(sempose::config::printable("x\u2028y\tz\u00e9"), "x\\u2028y\\tz\u00e9");
}

// 100,000 '[' or '{' (or an unclosed one followed by more): yaml-cpp stops at its depth limit
// with the message "bad file", which named nothing. Now the message says what is wrong.
TEST(ConfigFaults, DeepNestingIsNamedNotABadFile) {
  for (const std::string& text : {"scan: " + std::string(100000, '['), "scan: " + std::string(100000, '{'),
                                  "scan: " + std::string(5000, '[') + std::string(5000, ']')}) {
    AppConfig c;
    std::string e;
    EXPECT_FALSE(parse_app_config(text, "deep.yaml", c, e));
    EXPECT_NE(e.find("deep.yaml:1:"), std::string::npos) << e;
    EXPECT_NE(e.find("(syntax): lists or mappings nested too deep for the YAML reader"), std::string::npos) << e;
    EXPECT_EQ(e.find("bad file"), std::string::npos) << e;
  }
}

// Every numeric key at the exact edges of its allowed range, written as the range message
// prints them, is accepted; one step outside is refused. The reader compared the number as a
// long double with the bound as a double: "0.01" lies below the double 0.01, so
// `sim.beam_current_pa: 0.01` was "outside the allowed range [0.01, 100000]" (found probing:
// the minimum of 22 keys and the maximum of 2 refused).
TEST(ConfigFaults, EveryNumericKeyAcceptsTheEdgesOfItsRange) {
  const std::string dir = temp_dir();
  const std::string base = base_yaml(dir);
  const std::regex range_re(R"(is outside the allowed range \[([^,\]]+), ([^\]]+)\])");
  int keys = 0, edges = 0;
  std::vector<std::string> refused;
  for (const KeyInfo& k : config_keys(base)) {
    if (k.kind != KeyKind::kFloat && k.kind != KeyKind::kInteger) continue;
    AppConfig c;
    std::string e;
    parse_app_config(with(base, k.path, "1e300"), dir + "/c.yaml", c, e);
    std::smatch m;
    const auto at = e.find(k.path + ": ");
    if (at == std::string::npos) continue;
    const std::string line = e.substr(at, e.find('\n', at) - at);
    if (!std::regex_search(line, m, range_re)) continue;  // a bound that depends on other keys
    ++keys;
    for (const std::string& edge : {m[1].str(), m[2].str()}) {
      if (edge == "inf" || edge == "-inf") continue;
      ++edges;
      AppConfig ce;
      std::string ee;
      parse_app_config(with(base, k.path, edge), dir + "/c.yaml", ce, ee);
      if (ee.find(k.path + ": " + edge + " is outside the allowed range") != std::string::npos) {
        refused.push_back(k.path + " = " + edge);
      }
    }
    // One step outside the lower edge is still refused.
    if (m[1].str() != "-inf" && std::stod(m[1].str()) > -9e18) {
      const double lo = std::stod(m[1].str());
      const double below = k.kind == KeyKind::kInteger ? lo - 1 : (lo == 0 ? -1e-9 : lo - std::fabs(lo) * 1e-6);
      char text[64];
      std::snprintf(text, sizeof text, k.kind == KeyKind::kInteger ? "%.0f" : "%.17g", below);
      AppConfig cb;
      std::string eb;
      EXPECT_FALSE(parse_app_config(with(base, k.path, text), dir + "/c.yaml", cb, eb)) << k.path << " = " << text;
      EXPECT_NE(eb.find(k.path + ": "), std::string::npos) << k.path << " = " << text << ":\n" << eb;
    }
  }
  std::printf("%d keys with a fixed range, %d edges accepted\n", keys, edges);
  EXPECT_GE(keys, 80);
  std::string list;
  for (const auto& r : refused) list += "  " + r + "\n";
  EXPECT_TRUE(refused.empty()) << refused.size() << " range edges refused as outside their own range:\n" << list;
}

// A 64-bit integer key takes every value of its type: `sim.seed: 18446744073709551615` (2^64 - 1,
// which `sim --seed` takes) was refused as "outside the allowed range [0, inf]" — the bound was
// 1.8e19 and the message printed the type's maximum as inf. 2^64 is still refused, with the
// exact bounds.
TEST(ConfigFaults, A64BitKeyTakesItsWholeRangeAndNamesItExactly) {
  for (const char* v : {"18446744073709551615", "18000000000000000001", "0"}) {
    AppConfig c;
    std::string e;
    EXPECT_TRUE(parse_app_config(std::string("sim: {seed: ") + v + "}\n", "s.yaml", c, e)) << v << ": " << e;
    EXPECT_EQ(std::to_string(c.sim.seed), v);
  }
  for (const char* v : {"18446744073709551616", "-1", "1e300"}) {
    AppConfig c;
    std::string e;
    EXPECT_FALSE(parse_app_config(std::string("sim: {seed: ") + v + "}\n", "s.yaml", c, e)) << v;
    EXPECT_NE(e.find(std::string("sim.seed: ") + v + " is outside the allowed range [0, 18446744073709551615]"),
              std::string::npos) << e;
  }
}


// Found probing: as root, access() passes on /proc and /sys, so `output.hist_dir: /sys/kernel`
// was accepted and failed only at exit, and outputs in /proc failed after the inputs were read.
// The kernel's pseudo-filesystems are named up front.
TEST(ConfigFaults, OutputsOnTheKernelsPseudoFilesystemsAreRefused) {
  const std::string dir = temp_dir();
  const std::string base = base_yaml(dir);
  const std::pair<const char*, const char*> cases[] = {
      {"output.hist_dir", "/sys/kernel"}, {"output.hist_dir", "/proc/sempose_hist"}, {"output.poses_csv", "/proc/sempose.csv"}};
  for (const auto& [key, path] : cases) {
    AppConfig c;
    std::string e;
    EXPECT_FALSE(parse_app_config(with(base, key, std::string("'") + path + "'"), dir + "/c.yaml", c, e)) << key << " = " << path;
    EXPECT_NE(e.find(std::string(key) + ": '" + path + "'"), std::string::npos) << e;
    EXPECT_NE(e.find("filesystem"), std::string::npos) << e;
  }
}

// Found probing: 100k misspelt keys gave 81 MB of errors, each line with the whole list of the
// keys known there. The list comes once a section and the errors stop at 50 with a count.
TEST(ConfigFaults, ManyUnknownKeysGiveABoundedReport) {
  const std::string dir = temp_dir();
  std::string text = "tracker:\n";
  for (int i = 0; i < 5000; ++i) text += "  k" + std::to_string(i) + ": 1\n";
  AppConfig c;
  std::string e;
  EXPECT_FALSE(parse_app_config(text, dir + "/c.yaml", c, e));
  EXPECT_LT(e.size(), 20000u) << "the report grows with the file";
  EXPECT_NE(e.find("tracker.k0: unknown key (known here: "), std::string::npos) << e.substr(0, 2000);
  EXPECT_NE(e.find("tracker.k1: unknown key (the known ones are listed above)"), std::string::npos) << e.substr(0, 2000);
  EXPECT_NE(e.find("... and 4950 more errors (the first 50 shown)"), std::string::npos) << e.substr(e.size() - 500);
}

// A pattern larger than the scan field cannot be found in it: refused naming the key and the
// field (found probing: a 16x16 field failed in setup naming an internal function).
TEST(ConfigFaults, APatternLargerThanTheFieldIsRefused) {
  const std::string dir = temp_dir();
  AppConfig c;
  std::string e;
  EXPECT_FALSE(parse_app_config("scan: {field_w: 100, field_h: 100, max_roi_w: 100, max_roi_h: 100}\n"
                                "tracker: {pattern_size_px: 128, roi_size_px: 128}\n",
                                dir + "/c.yaml", c, e));
  EXPECT_NE(e.find("tracker.pattern_size_px: 128 px does not fit the 100x100 scan field"), std::string::npos) << e;
}

// Checks that span sections (a pattern file that is missing, an output that cannot be written, a
// schedule naming no target) said file:1:1 (noticed probing); they now point at the key's value,
// or at its nearest written parent when the key is a default.
TEST(ConfigFaults, ACrossSectionErrorIsLocatedAtItsKey) {
  AppConfig c;
  std::string e;
  const std::string text =
      "source: sim\n"
      "targets:\n"
      "  - name: a\n"
      "    pattern_sets:\n"
      "      - {file: here.pgm, nm_per_px: 40, dwell_ns: 2000}\n"
      "      - {file: missing.pgm, nm_per_px: 20, dwell_ns: 2000}\n"
      "output:\n"
      "  poses_csv: /proc/nope/p.csv\n"
      "pipeline:\n"
      "  schedule: [0, 3]\n";
  EXPECT_FALSE(parse_app_config(text, "l.yaml", c, e));
  EXPECT_NE(e.find("l.yaml:6:16: targets[0].pattern_sets[1].file: 'missing.pgm' is missing"), std::string::npos) << e;
  EXPECT_NE(e.find("l.yaml:8:14: output.poses_csv: '/proc/nope/p.csv' cannot be written"), std::string::npos) << e;
  EXPECT_NE(e.find("l.yaml:10:13: pipeline.schedule: 3 is not a target index"), std::string::npos) << e;
  EXPECT_EQ(e.find(":1:1:"), std::string::npos) << e;
  // A key left at its default is located at the nearest parent the file has.
  EXPECT_FALSE(parse_app_config("source: replay\nreplay:\n  loop: true\n", "r.yaml", c, e));
  EXPECT_NE(e.find("r.yaml:3:3: replay.frames_dir: required when source is replay"), std::string::npos) << e;
}

}  // namespace
}  // namespace sempose::config
