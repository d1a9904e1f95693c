// `marglab plot results/NAME...`: the paper's figures (Fig. 1, 4, 5, 6, 7 analogs) from sweep
// results, drawn by tools/scripts/plot_paper.py with a Python 3 that has matplotlib, h5py and
// numpy (found among $MARGLAB_PYTHON, /usr/bin/python3 and python3 on PATH — the first python3 on
// PATH may lack them).

#include <memory>

#include <fmt/core.h>

#include "core/common/error.h"
#include "core/experiment/plotting.h"
#include "core/frontend/track_figure.h"
#include "tools/command.h"
#include "tools/option_checks.h"

namespace marglab {
namespace {

const bool kRegistered = cli::registerCommand(
    {"plot", "Figures of the paper (Fig. 1, 4-7 analogs) from sweep results, PNG + PDF", 40,
     [](CLI::App& sub) -> cli::CommandRun {
       auto request = std::make_shared<experiment::PlotRequest>();
       auto tracks = std::make_shared<TrackFigureRequest>();
       sub.add_option("dirs", request->dirs, "Sweep folders (results/NAME), one or more")
           ->check(cli::existingPath("sweep folder", cli::PathKind::kFolder));
       sub.add_option("--figure", request->figures,
                      "Figures, comma-separated: fig1 (trajectories + sigma_min, VIO), fig4 (dEm, "
                      "VIO), fig4_yaw (yaw against roll/pitch in dEm, every seed, VIO; + .csv), "
                      "fig5 (dEm, VO), fig6 (sigma_min, VO), fig7 (trajectories, VO), "
                      "sparsify (Hsiung et al. Fig. 6a/6b and KLD of nfr runs), noise_sigma "
                      "(prior sigma_max / sigma_min at the first 20 marginalizations per IMU "
                      "noise profile, VIO); ba_convergence, ba_profile (`marglab ba` runs: cost "
                      "- best against time per problem, rootba's performance profile); tracks (one "
                      "stereo frame with its feature tracks, needs --dataset, no folders)")
           ->capture_default_str();
       sub.add_option("-o,--out", request->out,
                      "Output folder (default: notebooks-out/<name of the first folder>)");
       sub.add_option("--vio-dataset", request->vio_dataset,
                      "Sequence of Figs. 1 and 4 (else the first EuRoC / TUM-VI one present)")
           ->capture_default_str();
       sub.add_option("--vo-dataset", request->vo_dataset,
                      "Sequence of Figs. 5-7 (else the first KITTI one present)")
           ->capture_default_str();
       sub.add_option("--dataset", tracks->dataset,
                      "tracks: image folder or shipped name (euroc/V1_01_easy_images)");
       sub.add_option("--frame", tracks->frame, "tracks: stereo frame index")
           ->capture_default_str();
       sub.add_option("--tracks", tracks->tracks_file,
                      "tracks: draw this track file instead of running the front-end")
           ->check(cli::existingPath("--tracks", cli::PathKind::kFile));
       return [request, tracks] {
         if (request->figures == "tracks") {
           if (tracks->dataset.empty()) throw UsageError("--figure tracks needs --dataset");
           if (!request->out.empty()) tracks->out_dir = request->out;
           fmt::print("wrote {}\n", drawTrackFigure(*tracks));
           return 0;
         }
         if (request->dirs.empty()) throw UsageError("plot needs one or more sweep folders");
         return experiment::runPlot(*request);
       };
     }});

}  // namespace
}  // namespace marglab
