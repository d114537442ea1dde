use ecr_macros::ecr_method;

ecr_method!(r = 3, family = tc, family = rknc);

fn main() {}
