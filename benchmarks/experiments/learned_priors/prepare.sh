#!/usr/bin/env bash
# Trains the learned priors of the learned-priors table (models/, beside this file) on the whole shared corpus
# less what the table tracks: CMU without subjects 11 and 16, bandai2 without the style "exhausted" and without
# the content "wave-both-hands" (from $POSE_TRACKER_DATA_ROOT/mocap, default ../shared/mocap beside the checkout).
# Every prior with train's defaults, training seeds 0 and 1; two trainings at a time, each on one thread.
# Beside them, the CRBM and the neural prior on the CMU part alone (seed 0), to see what the second lab's data do,
# and a second fold (models/fold_b/, for fold_b.toml): CMU without subjects 49 and 91, bandai2 without the style
# "elderly" and the content "walk-turn-right", the CRBM and the neural prior, training seeds 0 and 1. In both folds
# the neural prior on the CMU part alone with training seeds 0 and 1 as well, as the pretrained model is trained
# (for likelihood_fold_a.toml and likelihood_fold_b.toml).
# bandai2 is CC BY-NC 4.0 (see the data's mocap/README.md): the models made here are for research, not to ship.
#   Bandai-Namco-Research-Motiondataset, Bandai Namco Research Inc. (2022), CC BY-NC 4.0; M. Kobayashi, C.-C. Liao,
#   K. Inoue, S. Yojima, M. Takahashi, "Motion Capture Dataset for Practical Use of AI-based Motion Editing and
#   Stylization", arXiv:2306.08861, 2023.
# Run from anywhere: bash benchmarks/experiments/learned_priors/prepare.sh   (about 52 min on two cores)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="${POSE_TRACKER_DATA_ROOT:-$here/../../../../shared}"
M="$(cd "$root/mocap" && pwd)"
fold() {  # models subfolder, two CMU subjects, a bandai2 style and a content, all left out of the training corpus
  out_dir="$here/models$1"
  mkdir -p "$out_dir"
  corpus=()
  while IFS= read -r f; do corpus+=("$f"); done < <(
    find "$M/cmu" \( -name '*.amc' -o -name '*.bvh' \) ! -path "*/$2/*" ! -name "$2_*" ! -path "*/$3/*" ! -name "$3_*" | sort
    find "$M/bandai2" -name '*.bvh' ! -name "*_$4_*" ! -name "*_$5_*" | sort)
  printf '%s\n' "${corpus[@]}" > "$out_dir/corpus.txt"
}
train() {  # prior seed [train options]: on the fold's corpus
  local prior="$1" seed="$2"; shift 2
  local out="$out_dir/${prior}_seed$seed.pt"
  [ -f "$out" ] || python -m tracker --threads 1 train --prior "$prior" --seed "$seed" --mocap "${corpus[@]}" \
      "$@" --out "$out" --resume
}
train_cmu() {  # prior [seed]: on the fold's CMU clips alone, seed 0 unless given
  local seed="${2:-0}"
  local out="$out_dir/${1}_cmu_seed$seed.pt"
  [ -f "$out" ] || python -m tracker --threads 1 train --prior "$1" --seed "$seed" \
      --mocap $(printf '%s\n' "${corpus[@]}" | grep '/cmu/') --out "$out" --resume
}
lane() {  # seed
  train neural "$1"
  train crbm "$1"
  train fcrbm "$1" --labels 'dataset-2_{content}_{style}_{take}#style' --unlabelled normal
  train gpdm "$1"
  train deep-crbm "$1"
}
fold "" 16 11 exhausted wave-both-hands
lane 0 & lane 1 & wait
train_cmu neural & train_cmu crbm & wait
train_cmu neural 1

fold /fold_b 49 91 elderly walk-turn-right
(train neural 0; train crbm 0) & (train neural 1; train crbm 1) & wait
train_cmu neural 0 & train_cmu neural 1 & wait
