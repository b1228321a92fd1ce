"""stable-baselines3 on the native vector env: hyperparameters (:mod:`.hyperparams`), resumable
training (:mod:`.training`), the residual-set-point VecEnv (:mod:`.vec_env`), the HER buffer
(:mod:`.her`) and saved models as policies (:mod:`.policy`)."""
