use ecr_macros::ecr_method;

ecr_method!(r = -1);

fn main() {}
