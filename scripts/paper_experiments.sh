#!/bin/bash
# The paper's experiments (issue #16), resumable: run it again after an interruption and it
# goes on (recording resumes its store, each sweep skips the jobs that finished).
#
#   bash scripts/paper_experiments.sh prep     # demonstrations and datasets (about 2 min)
#   bash scripts/paper_experiments.sh A        # Exp. 1, Exp. 3, the heightfield cross-soil sweep
#   bash scripts/paper_experiments.sh B        # Exp. 2, Exp. 4 (30 seeds)
#   bash scripts/paper_experiments.sh C        # the particle cross-soil sweep (after Exp. 3)
#   bash scripts/paper_experiments.sh D        # DANNet + p_t fine-tuned (PPO), on both soils
#   bash scripts/paper_experiments.sh report   # docs/results/paper from whatever has finished
#
# A and B may run at the same time (one core each), after prep; C after A's Exp. 3 (the
# particle pile ran about 0.6x real time on an idle core with its 20 CG iterations (30 since
# session 30: digging about twice as slow), so C evaluates the same
# controllers on summer and winter_c only, 4 episodes per seed: about 1.5 hours (20
# iterations; about 3 with 30) on one
# core; a third process on a 2-core machine, so better after A or B). Run from the repository root;
# PYTHON defaults to .venv/bin/python, NICE to 10. EXPERT adds scripted-expert overrides to
# prep's recordings: EXPERT="+expert.impact_cue=rise +expert.push_again=false" records with
# the operator before session 33, the one docs/results/paper/ was made with (into a fresh
# data/demos and data/datasets: a store recorded by another expert, and a dataset built from
# another recording, are refused; EXPERT must not set trigger_sensor, which the winter_c
# recording sets itself). Each step's output goes to
# logs/paper_experiments/<step>.out and its start and end to logs/paper_experiments/steps.log.
set -u
PYTHON=${PYTHON:-.venv/bin/python}
NICE=${NICE:-10}
# EXPERT's overrides as words (split on spaces, never glob-expanded)
read -ra EXPERT_ARGS <<< "${EXPERT:-}"
LOGS=logs/paper_experiments
mkdir -p "$LOGS"
export OMP_NUM_THREADS=1

step() {
    local name=$1
    shift
    echo "== $name start $(date -u +%FT%T) load $(cut -d' ' -f1-3 /proc/loadavg)" >> "$LOGS/steps.log"
    nice -n "$NICE" "$PYTHON" "$@" >> "$LOGS/$name.out" 2>&1
    local rc=$?
    echo "== $name end $(date -u +%FT%T) rc $rc" >> "$LOGS/steps.log"
    if [ $rc -ne 0 ]; then
        echo "paper_experiments: step $name failed (exit $rc); see $LOGS/$name.out" >&2
        exit $rc
    fi
}

# the Exp. 3 controllers with p_t on D_II (jobs 3, 5, 9, 11, 15, 17 and their seeds 1 and 2)
exp3_with_pt() {
    local jobs=() job seed
    for job in 3 5 9 11 15 17; do
        for seed in 0 18 36; do jobs+=("multirun/exp3_attention/$((job + seed))"); done
    done
    local IFS=,
    echo "${jobs[*]}"
}

case ${1:-} in
prep)
    step record_summer recipes/record.py "${EXPERT_ARGS[@]}"
    step record_winter_c recipes/record.py env.condition=winter_c n_episodes=10 \
        +expert.trigger_sensor=telescope_pressure out_dir=data/demos/winter_c_validation \
        "${EXPERT_ARGS[@]}"
    step build_datasets recipes/build_dataset.py --multirun dataset=d_i,d_ii
    ;;
A)
    step exp1 recipes/train_bc.py --multirun +experiment=exp1_summer_to_winter evaluation.workers=1
    step exp3 recipes/train_bc.py --multirun +experiment=exp3_attention evaluation.workers=1
    step cross_soil_heightfield recipes/evaluate.py --multirun env.soil=heightfield \
        "checkpoint=$(exp3_with_pt)" "evaluation.conditions=[summer,winter,held_out]" \
        evaluation.episodes=10 evaluation.workers=1 evaluation.videos=false \
        hydra.sweep.dir=multirun/cross_soil_heightfield
    ;;
B)
    step exp2 recipes/train_bc.py --multirun +experiment=exp2_data_and_pt evaluation.workers=1
    step exp4 recipes/train_bc.py --multirun +experiment=exp4_offline_validation ensemble_seeds=30
    ;;
C)
    step cross_soil_particles recipes/evaluate.py --multirun env.soil=particles \
        "checkpoint=$(exp3_with_pt)" "evaluation.conditions=[summer,winter_c]" \
        evaluation.episodes=4 evaluation.workers=1 evaluation.videos=false \
        hydra.sweep.dir=multirun/cross_soil_particles
    ;;
D)
    for seed in 0 1 2; do  # Exp. 3's DANNet + p_t on D_II, seeds 0-2 (jobs 15, 33, 51)
        step "finetune_seed$seed" recipes/finetune.py \
            "checkpoint=multirun/exp3_attention/$((15 + 18 * seed))/best.pt" \
            curriculum=winter_focus curriculum.stages.0.frames=200000 "seed=$seed" \
            "hydra.run.dir=multirun/finetune_exp3/dannet_pt_d_ii_seed$seed"
    done
    tuned=multirun/finetune_exp3/dannet_pt_d_ii_seed0/best.pt
    tuned+=,multirun/finetune_exp3/dannet_pt_d_ii_seed1/best.pt
    tuned+=,multirun/finetune_exp3/dannet_pt_d_ii_seed2/best.pt
    step cross_soil_heightfield_finetuned recipes/evaluate.py --multirun env.soil=heightfield \
        "checkpoint=$tuned" "evaluation.conditions=[summer,winter,held_out]" \
        evaluation.episodes=10 evaluation.workers=1 evaluation.videos=false \
        hydra.sweep.dir=multirun/cross_soil_heightfield_finetuned
    step cross_soil_particles_finetuned recipes/evaluate.py --multirun env.soil=particles \
        "checkpoint=$tuned" "evaluation.conditions=[summer,winter_c]" \
        evaluation.episodes=4 evaluation.workers=1 evaluation.videos=false \
        hydra.sweep.dir=multirun/cross_soil_particles_finetuned
    ;;
report)
    args=()
    for n in 1 2 3 4; do
        dir=$(ls -d multirun/exp${n}_* 2>/dev/null | head -1)
        [ -n "$dir" ] && args+=("--exp$n" "$dir")
    done
    soils=()
    for dir in multirun/cross_soil_*; do  # one sweep per soil, and any parts and additions
        [ -d "$dir" ] && soils+=("$dir")
    done
    [ ${#soils[@]} -gt 0 ] && args+=(--cross-soil "${soils[@]}")
    step report -m pilerl.reports.paper "${args[@]}" \
        --figure-actor NNetV2=multirun/exp3_attention/5/best.pt \
        --figure-actor DANNet=multirun/exp3_attention/17/best.pt \
        --figure-demos data/demos/winter_c_validation --out docs/results/paper
    ;;
*)
    echo "usage: bash scripts/paper_experiments.sh prep|A|B|C|D|report" >&2
    exit 2
    ;;
esac
