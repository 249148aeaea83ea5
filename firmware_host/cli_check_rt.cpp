// `sempose check-rt`: the RT preflight a lab engineer runs before trusting a box. One line
// per check (PASS / WARN / FAIL and the fix), a summary line, and an exit code for scripts:
// 0 all pass, 1 warnings only, 3 a failure, 2 usage or config errors. `--root DIR` reads
// DIR/proc, DIR/sys and DIR/dev instead of the live ones (tests, or a copied tree).
#include <cstdio>
#include <filesystem>
#include <cstring>
#include <string>

#include "cli.hpp"
#include "cli_options.hpp"
#include "sempose/check_rt/checks.hpp"
#include "sempose/config/app_config.hpp"
#include "sempose/config/reader.hpp"

namespace {

int usage(std::FILE* out) {
  std::fprintf(out,
               "usage: sempose check-rt [--config FILE] [--root DIR]\n"
               "  --config FILE  check what this config needs (RT cores, priorities, CAN, GPIO, source);\n"
               "                 default: the built-in defaults\n"
               "  --root DIR     read DIR/proc, DIR/sys, DIR/dev instead of the live system (CAN and GPIO\n"
               "                 details still come from the live kernel)\n"
               "exit code: 0 all pass, 1 warnings only, 3 at least one failure, 2 usage/config error\n");
  return out == stdout ? 0 : 2;
}

}  // namespace

int sempose::cli::print_rt_checks(const config::AppConfig& cfg, const std::string& root) {
  check_rt::SystemTree tree(root);
  check_rt::LinuxProbe probe;
  const auto results = check_rt::run_checks(tree, cfg, probe);
  int counts[3] = {0, 0, 0};
  for (const auto& r : results) {
    // The tree's own text (a kernel version, a governor) is quoted in the lines: escaped and
    // bounded (a terminal escape in osrelease retitled the terminal; hostile round 9).
    std::printf("%s\n", config::terminal_text(check_rt::format_result(r)).c_str());
    ++counts[static_cast<int>(r.level)];
  }
  std::printf("check-rt: %d pass, %d warn, %d fail\n", counts[0], counts[1], counts[2]);
  std::fflush(stdout);
  return check_rt::exit_code(results);
}

int sempose::cli::check_rt(int argc, char** argv) {
  const ParsedOptions opt = parse_options({text("--config"), text("--root")}, argc, argv);
  if (const int code = finish_parse("check-rt", opt, usage); code >= 0) return code;
  const std::string config_path = opt.text("--config"), root = opt.text("--root", "/");
  std::error_code ec;
  if (!std::filesystem::is_directory(root, ec)) {
    std::fprintf(stderr, "sempose check-rt: --root '%s' is not a directory (a system tree with proc/, sys/, dev/)\n",
                 root.c_str());
    return 2;
  }
  config::AppConfig cfg;
  if (!config_path.empty()) {
    std::string errors;
    // Outputs this user cannot write are one of the checks (FAIL outputs), not a config error
    // that hid every RT check (found probing: check-rt as the service user before its log folder
    // was made stopped at "invalid config").
    if (!config::load_app_config(config_path, cfg, errors, config::OutputCheck::kLeaveToCaller)) {
      std::fprintf(stderr, "sempose check-rt: invalid config:\n%s", errors.c_str());
      return 2;
    }
  }
  const int code = print_rt_checks(cfg, root);
  // The report lost (stdout on a full disk): said on stderr; a passing check is not a pass unseen.
  return report_lost("check-rt") && code == 0 ? 4 : code;
}
