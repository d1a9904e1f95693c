#include "core/experiment/slurm_script.h"

#include <fmt/core.h>

#include <cmath>
#include <fstream>
#include <sstream>

#include "core/experiment/sweep_runner.h"

namespace marglab::experiment {
namespace {

std::string directives(const SlurmArraySpec& spec) {
  std::string text;
  auto add = [&](const std::string& option) { text += "#SBATCH " + option + "\n"; };
  add("--job-name=marglab-" + spec.sweep_name);
  const int last = static_cast<int>(spec.tasks.size()) - 1;
  add(fmt::format("--array=0-{}{}", last,
                  spec.throttle > 0 ? fmt::format("%{}", spec.throttle) : std::string()));
  add("--chdir=" + spec.sweep_dir);
  // Slurm's own output of the task (the run's output goes to logs/<id>.log).
  add("--output=" + spec.sweep_dir + "/slurm/out/%A_%a.out");
  add("--ntasks=1");
  add(fmt::format("--cpus-per-task={}", spec.cpus));
  if (!spec.time.empty()) add("--time=" + spec.time);
  if (!spec.partition.empty()) add("--partition=" + spec.partition);
  if (!spec.mem.empty()) add("--mem=" + spec.mem);
  if (!spec.after_ok.empty()) {
    std::string jobs;
    for (const std::string& job : spec.after_ok) jobs += ":" + job;
    add("--dependency=afterok" + jobs);
    add("--kill-on-invalid-dep=yes");
  }
  for (const std::string& option : spec.extra) add(option);
  return text;
}

std::string taskTable(const SlurmArraySpec& spec) {
  std::string text = "case \"$SLURM_ARRAY_TASK_ID\" in\n";
  for (std::size_t i = 0; i < spec.tasks.size(); ++i) {
    const SlurmTask& task = spec.tasks[i];
    text +=
        fmt::format("  {}) ID={}; set -- {} ;;\n", i, shellJoin({task.id}), shellJoin(task.args));
  }
  text += "  *) echo \"marglab: no run for array task $SLURM_ARRAY_TASK_ID\" >&2; exit 2 ;;\n";
  return text + "esac\n";
}

// The task body: why each step is there is in the header.
const char* const kTaskBody = R"SH(
LOG="logs/$ID.log"
EXIT="slurm/exit/$ID"
TASK="${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID}"
START=$(date +%s.%N)
record() {
  echo "$1 start=$START end=$(date +%s.%N) job=$TASK host=$(hostname -s)" > "$EXIT.tmp.$$" &&
    mv -f "$EXIT.tmp.$$" "$EXIT"
}
trap 'record signal=TERM; exit 143' TERM
rm -f "$EXIT"
echo "# slurm task $TASK on $(hostname -s), started $(date -u +%Y-%m-%dT%H:%M:%SZ)" >> "$LOG"
case "$("$EXE" --version 2>&1)" in
  *"(git $REVISION)"*) ;;
  *) echo "marglab: $EXE is no longer git revision $REVISION, which planned this sweep:" \
          "rebuild it or resubmit (marglab sweep --resume)" >> "$LOG"
     record exit=3; exit 3 ;;
esac
"$EXE" "$@" >> "$LOG" 2>&1
CODE=$?
record exit=$CODE
exit $CODE
)SH";

}  // namespace

std::string sbatchScript(const SlurmArraySpec& spec) {
  std::string text = "#!/bin/bash\n";
  text += fmt::format(
      "# marglab sweep {}: {} run(s) as one Slurm job array, written by `marglab sweep --backend "
      "slurm`.\n# Submitted as: sbatch --parsable <this file>. Task N runs the N-th marglab "
      "command below.\n",
      spec.sweep_name, spec.tasks.size());
  text += directives(spec);
  text += "set -u\n";
  text += "EXE=" + shellJoin({spec.executable}) + "\n";
  text += "REVISION=" + shellJoin({spec.revision}) + "\n";
  text += taskTable(spec);
  return text + kTaskBody;
}

std::string slurmTimeForTimeout(double timeout_s) {
  if (!(timeout_s > 0)) return {};
  return std::to_string(static_cast<long>(std::ceil(timeout_s / 60.0)));
}

TaskExit readTaskExit(const std::string& path) {
  TaskExit exit;
  std::ifstream in(path);
  if (!in) return exit;
  std::string word;
  while (in >> word) {
    const auto eq = word.find('=');
    if (eq == std::string::npos) continue;
    const std::string key = word.substr(0, eq), value = word.substr(eq + 1);
    if (key == "exit") exit.exit_code = std::atoi(value.c_str());
    if (key == "signal") exit.signal = value;
    if (key == "start") exit.start = std::atof(value.c_str());
    if (key == "end") exit.end = std::atof(value.c_str());
    if (key == "job") exit.job = value;
    exit.present = true;
  }
  return exit;
}

}  // namespace marglab::experiment
