from ilc_steering.agents.adapters import PullLearner
from ilc_steering.agents.bayes_opt import bayes_opt
from ilc_steering.boxes import SearchBox


def _make(k):
    def make(context):
        def run(env):
            bayes_opt(SearchBox(env, *context.search_box()), context, refit_every=k)

        return PullLearner(run, context.action_space, context.observation_space)

    return make


refit1 = _make(1)
refit8 = _make(8)
