#!/usr/bin/env bash
# Renders the protocol's sequences (sequences/) and trains its CRBMs (models/) beside this file, from
# the shared data's mocap/cmu (the data root: $POSE_TRACKER_DATA_ROOT, default ../shared beside the checkout).
# Three folds, each leaving out the subjects it tracks:
#   B (tuning): subjects 2 and 10 left out;  A (report): 16, 49, 11 and 131 left out;  C (report): 91 left out.
# Each fold has a CRBM trained on the walks of the other subjects and one trained on all their clips.
# Run from anywhere: bash benchmarks/experiments/motion_mixture/prepare.sh   (about 30 min on two cores)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="${POSE_TRACKER_DATA_ROOT:-$here/../../../../shared}"
M="$(cd "$root/mocap/cmu" && pwd)"
mkdir -p "$here/sequences" "$here/models"
render() {  # name clip start frames [synth options]
  local name="$1" clip="$2" start="$3" frames="$4"; shift 4
  [ -d "$here/sequences/$name" ] || python -m tracker --threads 1 synth --mocap "$clip" --start "$start" \
      --frames "$frames" "$@" --out "$here/sequences/$name"
}
render walk_02 "$M/02/02_01.amc" 0 150
render walk_02_turned "$M/02/02_01.amc" 0 150 --turn 90
render punch_02 "$M/02/02_05.amc" 200 150
render kick_10 "$M/bvh/10_01.bvh" 100 150
render walk_16 "$M/16/16_15.amc" 0 150
render run_16 "$M/16/16_35.amc" 0 80
render whole_49 "$M/49/49_18.amc" 100 150
render kick_11 "$M/bvh/11_01.bvh" 100 150
render startwalk_131 "$M/bvh/131_01.bvh" 90 150
render walk_91 "$M/91/91_straight_walk.amc" 0 150
render sadwalk_91 "$M/91/91_sad_walk.amc" 200 150

runs9="$M/09/09_01.amc $M/09/09_02.amc $M/09/09_03.amc $M/09/09_04.amc $M/09/09_05.amc"
walks7="$M/07/07_01.amc $M/07/07_02.amc $M/07/07_09.amc $M/07/07_10.amc"
walks_A="$M/02/02_01.amc $M/02/02_02.amc $walks7 $M/91/91_straight_walk.amc"
all_A="$walks_A $M/02/02_03.amc $M/02/02_05.amc $runs9 $M/bvh/10_01.bvh $M/bvh/10_03.bvh"
walks_B="$walks7 $M/16/16_15.amc $M/91/91_straight_walk.amc"
all_B="$walks_B $runs9 $M/16/16_35.amc $M/16/16_36.amc $M/49/49_18.amc $M/bvh/11_01.bvh $M/bvh/131_01.bvh"
walks_C="$M/02/02_01.amc $M/02/02_02.amc $walks7 $M/16/16_15.amc"
all_C="$walks_C $M/02/02_03.amc $M/02/02_05.amc $runs9 $M/16/16_35.amc $M/16/16_36.amc $M/49/49_18.amc \
$M/bvh/10_01.bvh $M/bvh/11_01.bvh $M/bvh/131_01.bvh"
train() {  # name seed clips...
  local name="$1" seed="$2"; shift 2
  [ -f "$here/models/$name.pt" ] || python -m tracker --threads 1 train --prior crbm --seed "$seed" --mocap "$@" \
      --out "$here/models/$name.pt"
}
for fold in A B C; do
  eval "train crbm_walks_$fold 0 \$walks_$fold"
  eval "train crbm_all_$fold 0 \$all_$fold"
done
for fold in A C; do  # the report folds' walk-trained CRBM with a second training seed
  eval "train crbm_walks_${fold}_seed1 1 \$walks_$fold"
done

# An FCRBM per fold on every activity, one style label per clip (in the order of all_<fold>)
fcrbm() {  # name labels clips...
  local name="$1" labels="$2"; shift 2
  [ -f "$here/models/$name.pt" ] || python -m tracker --threads 1 train --prior fcrbm --labels "$labels" \
      --mocap "$@" --out "$here/models/$name.pt"
}
eval "fcrbm fcrbm_all_B walk,walk,walk,walk,walk,walk,run,run,run,run,run,run,run,whole,kick,walk \$all_B"
eval "fcrbm fcrbm_all_A walk,walk,walk,walk,walk,walk,walk,run,punch,run,run,run,run,run,kick,kick \$all_A"
eval "fcrbm fcrbm_all_C walk,walk,walk,walk,walk,walk,walk,run,punch,run,run,run,run,run,run,run,whole,kick,kick,walk \$all_C"
